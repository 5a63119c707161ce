#pragma once
// Shared helpers of the bindings: numpy <-> sonar3d types. Outputs are zero-copy wherever the
// memory layout allows: a std::vector produced by the library is moved into a capsule that owns
// it and becomes the array's base; inputs are read through a C-contiguous view and copied once
// into the library's own types (they own std::vector storage).
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/mesh.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/core/sonar_image.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/eval/metrics.hpp"

namespace sonar3d::python {

namespace py = pybind11;

template <class T>
using carray = py::array_t<T, py::array::c_style | py::array::forcecast>;

// Moves `v` into an array of `shape` (row-major) without copying the elements.
template <class T, class E = T>
py::array_t<E> adopt(std::vector<T>&& v, std::vector<py::ssize_t> shape) {
  static_assert(sizeof(T) % sizeof(E) == 0, "element type must tile the stored type");
  auto* owner = new std::vector<T>(std::move(v));
  py::capsule base(owner, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<E>(shape, reinterpret_cast<E*>(owner->data()), base);
}

// A view of memory owned by the Python object `owner` (kept alive by the array).
template <class T>
py::array_t<T> view(const T* data, std::vector<py::ssize_t> shape, py::handle owner) {
  py::array_t<T> a(shape, data, owner);
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return a;
}

// rows × cols float32 array holding the image's storage (no copy).
inline py::array_t<float> image_to_array(SonarImage&& img) {
  const py::ssize_t r = img.rows, c = img.cols;
  return adopt(std::move(img.data), {r, c});
}

// Copies a 2-D array (any real dtype, converted to float32) into a SonarImage.
inline SonarImage array_to_image(const carray<float>& a, const char* what = "image") {
  if (a.ndim() != 2) {
    throw Error(std::string(what) + " must be a 2-D array (range bins × beams), got " +
                std::to_string(a.ndim()) + " dimensions");
  }
  SonarImage img(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)));
  std::copy(a.data(), a.data() + a.size(), img.data.begin());
  return img;
}

inline py::array_t<double> pose_to_array(const Eigen::Isometry3d& T) {
  py::array_t<double> a({4, 4});
  auto m = a.mutable_unchecked<2>();
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) m(i, j) = T.matrix()(i, j);
  return a;
}

// A 4×4 rigid transform; throws Error naming `what` otherwise.
inline Eigen::Isometry3d array_to_pose(const carray<double>& a, const std::string& what = "pose") {
  if (a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4) {
    throw Error(what + " must be a 4×4 matrix");
  }
  Eigen::Isometry3d T;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) T.matrix()(i, j) = a.at(i, j);
  if (!is_rigid(T, 1e-5)) throw Error(what + " is not a rigid transform");
  return T;
}

// N × 4 × 4 stack of poses.
inline py::array_t<double> poses_to_array(const std::vector<Eigen::Isometry3d>& poses) {
  py::array_t<double> a({static_cast<py::ssize_t>(poses.size()), py::ssize_t{4}, py::ssize_t{4}});
  auto m = a.mutable_unchecked<3>();
  for (std::size_t k = 0; k < poses.size(); ++k)
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) m(k, i, j) = poses[k].matrix()(i, j);
  return a;
}

inline std::vector<Eigen::Isometry3d> array_to_poses(const carray<double>& a,
                                                     const std::string& what = "poses") {
  if (a.ndim() == 2) return {array_to_pose(a, what)};
  if (a.ndim() != 3 || a.shape(1) != 4 || a.shape(2) != 4) {
    throw Error(what + " must be an N×4×4 array of rigid transforms");
  }
  std::vector<Eigen::Isometry3d> out(a.shape(0));
  auto m = a.unchecked<3>();
  for (py::ssize_t k = 0; k < a.shape(0); ++k) {
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) out[k].matrix()(i, j) = m(k, i, j);
    if (!is_rigid(out[k], 1e-5)) {
      throw Error(what + "[" + std::to_string(k) + "] is not a rigid transform");
    }
  }
  return out;
}

// N × 3 float32 view of the points' storage (Eigen::Vector3f is three packed floats).
inline py::array_t<float> points_to_array(std::vector<Eigen::Vector3f>&& pts) {
  static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float), "Vector3f must be packed");
  const py::ssize_t n = static_cast<py::ssize_t>(pts.size());
  return adopt<Eigen::Vector3f, float>(std::move(pts), {n, 3});
}

inline std::vector<Eigen::Vector3f> array_to_points(const carray<float>& a,
                                                    const std::string& what = "points") {
  if (a.ndim() != 2 || a.shape(1) != 3) throw Error(what + " must be an N×3 array");
  std::vector<Eigen::Vector3f> out(a.shape(0));
  std::copy(a.data(), a.data() + a.size(), out.empty() ? nullptr : out[0].data());
  return out;
}

// The `progress` argument of the long calls: None/False (silent), True (the terminal bars the CLI
// shows, on stderr) or a callable progress(done, total). run() calls the library with the GIL
// released, inside a ScopedProgressCallback (core/progress.hpp) that forwards every stage of the
// call to the callable with the GIL held. An exception the callable raises stops further reports
// and is raised again once the library call returns.
class ProgressArg {
 public:
  explicit ProgressArg(const py::object& progress) {
    if (progress.is_none()) return;
    if (py::isinstance<py::bool_>(progress)) {
      terminal_ = progress.cast<bool>();
    } else if (PyCallable_Check(progress.ptr())) {
      callback_ = progress;
    } else {
      throw py::type_error("progress must be None, a bool or a callable progress(done, total)");
    }
  }
  ~ProgressArg() = default;
  ProgressArg(const ProgressArg&) = delete;
  ProgressArg& operator=(const ProgressArg&) = delete;

  bool terminal() const { return terminal_; }  // the library's `bool progress` (terminal bars)

  template <class F>
  auto run(F&& f) -> decltype(f()) {
    std::optional<decltype(f())> result;
    {
      ScopedProgressCallback scope(
          callback_ ? ProgressCallback([this](const std::string&, std::size_t done,
                                              std::size_t total) { report(done, total); })
                    : ProgressCallback());
      py::gil_scoped_release release;
      result.emplace(f());
    }
    if (error_) {
      py::error_already_set e = std::move(*error_);
      error_.reset();
      throw e;
    }
    return std::move(*result);
  }

 private:
  void report(std::size_t done, std::size_t total) noexcept {
    py::gil_scoped_acquire gil;
    if (error_) return;
    try {
      callback_(done, total);
    } catch (py::error_already_set& e) {
      error_ = std::move(e);
    }
  }
  py::object callback_;
  bool terminal_ = false;
  std::optional<py::error_already_set> error_;
};

// A JSON text (the library's one serialisation of a result) as Python objects.
inline py::object json_loads(const std::string& text) {
  return py::module_::import("json").attr("loads")(text);
}

// A config built from keyword arguments: C() with each keyword set as an attribute (so unknown
// names raise AttributeError and values go through the bound setters' checks).
template <class C>
C from_kwargs(const py::kwargs& kw) {
  C c;
  py::object o = py::cast(&c, py::return_value_policy::reference);
  for (auto item : kw) py::setattr(o, item.first, item.second);
  return c;
}

// A __repr__ listing every property of the object's class in declaration order, e.g.
// CarveConfig(voxel_size=0.01, region=None, ...); arrays of more than 8 values are summarised by
// shape. Bound as .def("__repr__", &fields_repr).
inline std::string fields_repr(const py::object& self) {
  const py::object type = py::type::of(self);
  const py::object property = py::module_::import("builtins").attr("property");
  const py::object ndarray = py::module_::import("numpy").attr("ndarray");
  std::string out = type.attr("__name__").cast<std::string>() + "(";
  bool first = true;
  for (const auto item : type.attr("__dict__").attr("items")()) {
    const auto kv = item.cast<py::tuple>();
    const auto name = kv[0].cast<std::string>();
    if (name.empty() || name[0] == '_' || !py::isinstance(kv[1], property)) continue;
    const py::object value = self.attr(kv[0]);
    std::string text;
    if (py::isinstance(value, ndarray) && value.attr("size").cast<py::ssize_t>() > 8) {
      text = "<array shape " + py::repr(value.attr("shape")).cast<std::string>() + " " +
             py::str(value.attr("dtype")).cast<std::string>() + ">";
    } else {
      text = py::repr(value).cast<std::string>();
    }
    out += (first ? "" : ", ") + name + "=" + text;
    first = false;
  }
  return out + ")";
}

// A mesh from a Mesh object, a (vertices, triangles) pair or a file path.
TriangleMesh to_mesh(const py::object& o);

// An EvalResult as a dict (errors in metres, fractions in [0, 1]); shared by eval and mapping.
py::dict result_dict(const EvalResult& r);

void bind_core(py::module_& m);
void bind_io(py::module_& m);
void bind_sim(py::module_& m);
void bind_recon(py::module_& m);
void bind_eval(py::module_& m);
void bind_mapping(py::module_& m);
void bind_recog(py::module_& m);
void bind_video(py::module_& m);
void bind_world(py::module_& m);
void bind_change(py::module_& m);
void bind_pipeline(py::module_& m);
void bind_online(py::module_& m);

}  // namespace sonar3d::python
