// Catalogue YAML of CAD-model recognition (read_catalogue), then, for entries naming a
// procedural reference object, the mesh and the model template (scale and sampling limits).
// Mesh files named by the catalogue are not loaded here (fuzz_mesh covers load_mesh).
#include "fuzz_common.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/recog/model.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto dir = sonar3d::fuzz::scratch() / "catalogue";
  sonar3d::fuzz::write_file(dir / "catalogue.yaml",
                            std::string_view(reinterpret_cast<const char*>(data), size));
  sonar3d::fuzz::run([&] {
    const sonar3d::Catalogue c = sonar3d::read_catalogue((dir / "catalogue.yaml").string());
    sonar3d::ModelSamplingConfig sampling;
    sampling.spacing_m = 0.05;
    for (const auto& m : c.models) {
      if (m.reference.empty()) continue;
      const sonar3d::TriangleMesh mesh = sonar3d::load_catalogue_mesh(c, m);
      sonar3d::make_model_template(m.name, mesh, m.symmetry, m.expected, sampling);
    }
  });
  return 0;
}
