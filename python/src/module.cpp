// The compiled part of the `sonar3d` Python package (sonar3d/_sonar3d). One file per area:
// core.cpp (sensor, poses, clouds, meshes), io.cpp (datasets, imports), sim.cpp (simulation),
// recon.cpp (denoise, carve, deconvolve), eval.cpp (metrics), mapping.cpp (elevation maps, swath
// registration, field surveys), recog.cpp (CAD-model recognition), video.cpp (cameras,
// video mapping), world.cpp (world models), change.cpp (change detection between surveys),
// pipeline.cpp (whole workflows: survey), online.cpp (online maps). No algorithm lives here.
#include "common.hpp"
#include "sonar3d/version.hpp"

PYBIND11_MODULE(_sonar3d, m) {
  namespace py = pybind11;
  m.doc() =
      "sonar3d: 3D maps from 2D imaging-sonar images (simulation, import, denoising, "
      "reconstruction, evaluation).\n\n"
      "Units are SI (metres, seconds, radians). Images are float32 arrays of range bins × beams "
      "(row 0 nearest), poses 4×4 float64 arrays T_world_sonar (sonar frame: +x boresight, +y "
      "left, +z up), point clouds N×3 float32 arrays in the world frame.";
  m.attr("__version__") = SONAR3D_VERSION;
  py::register_exception<sonar3d::Error>(m, "Error", PyExc_RuntimeError);
  sonar3d::python::bind_core(m);
  sonar3d::python::bind_io(m);
  sonar3d::python::bind_sim(m);
  sonar3d::python::bind_recon(m);
  sonar3d::python::bind_eval(m);
  sonar3d::python::bind_mapping(m);
  sonar3d::python::bind_recog(m);
  sonar3d::python::bind_video(m);
  sonar3d::python::bind_change(m);  // before world: RelocalizeConfig holds a registration
  sonar3d::python::bind_world(m);
  sonar3d::python::bind_pipeline(m);
  sonar3d::python::bind_online(m);
}
