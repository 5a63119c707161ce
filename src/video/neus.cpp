// IDR/NeuS cameras_*.npz: projection matrices decomposed into intrinsics and poses.
#include "sonar3d/video/neus.hpp"

#include <Eigen/QR>
#include <cmath>
#include <exception>
#include <sstream>
#include <string>
#include <vector>

#include "sonar3d/core/error.hpp"
#include "sonar3d/video/npz.hpp"

namespace sonar3d {

void decompose_projection(const Eigen::Matrix<double, 3, 4>& P_in, Eigen::Matrix3d* K_out,
                          Eigen::Isometry3d* T_world_camera) {
  require(P_in.allFinite(), "projection matrix is not finite");
  Eigen::Matrix<double, 3, 4> P = P_in;
  // A projection matrix is defined up to scale, also a negative one: choose the sign that makes
  // det(M) > 0 so that R comes out a rotation (det +1) with K's diagonal positive.
  Eigen::Matrix3d M = P.leftCols<3>();
  const double det = M.determinant();
  require(std::isfinite(det) && std::abs(det) > 1e-12 * std::pow(M.norm(), 3),
          "projection matrix is singular (its left 3×3 block has no inverse)");
  if (det < 0) {
    P = -P;
    M = -M;
  }
  // RQ from QR: with J the row-reversal, (J·M)ᵀ = Q·U gives M = (J·Uᵀ·J)·(J·Qᵀ), the first factor
  // upper triangular, the second orthogonal.
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
  J(0, 2) = J(1, 1) = J(2, 0) = 1;
  const Eigen::HouseholderQR<Eigen::Matrix3d> qr((J * M).transpose());
  const Eigen::Matrix3d Q = qr.householderQ();
  const Eigen::Matrix3d U = qr.matrixQR().triangularView<Eigen::Upper>();
  Eigen::Matrix3d K = J * U.transpose() * J;
  Eigen::Matrix3d R = J * Q.transpose();
  // Positive diagonal: K·D, D·R with D = diag(sign K_ii) (D² = I).
  for (int i = 0; i < 3; ++i) {
    if (K(i, i) < 0) {
      K.col(i) *= -1;
      R.row(i) *= -1;
    }
  }
  const Eigen::Vector3d C = -M.inverse() * P.col(3);  // P·(C, 1) = 0
  K /= K(2, 2);
  *K_out = K;
  T_world_camera->setIdentity();
  T_world_camera->linear() = R.transpose();
  T_world_camera->translation() = C;
}

namespace {

Eigen::Matrix4d matrix4(const NpyArray& a, const std::string& where, bool allow_3x4) {
  const bool is44 = a.shape == std::vector<std::size_t>{4, 4};
  const bool is34 = a.shape == std::vector<std::size_t>{3, 4};
  if (!is44 && !(allow_3x4 && is34)) {
    std::string s;
    for (std::size_t d : a.shape) s += (s.empty() ? "" : "×") + std::to_string(d);
    throw Error(where + " has shape (" + s + "), " + (allow_3x4 ? "3×4 or " : "") + "4×4 expected");
  }
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  for (int r = 0; r < (is44 ? 4 : 3); ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = a.data[static_cast<std::size_t>(4 * r + c)];
  }
  if (!m.allFinite()) throw Error(where + " is not finite");
  return m;
}

}  // namespace

std::vector<NeusCamera> read_neus_cameras(const std::filesystem::path& npz, NeusFrame frame) {
  const auto arrays = read_npz(npz);
  std::vector<NeusCamera> out;
  for (std::size_t i = 0;; ++i) {
    const std::string wname = "world_mat_" + std::to_string(i);
    const auto w = arrays.find(wname);
    if (w == arrays.end()) break;
    const std::string where = npz.string() + ": " + wname;
    const Eigen::Matrix4d W = matrix4(w->second, where, true);
    if (w->second.shape[0] == 4 && (W.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9) {
      throw Error(where + ": a 4×4 world_mat must end with the row 0 0 0 1");
    }
    NeusCamera cam;
    try {
      decompose_projection(W.topRows<3>(), &cam.K, &cam.T_world_camera);
    } catch (const Error& e) {
      throw Error(where + ": " + e.what());
    }
    const std::string sname = "scale_mat_" + std::to_string(i);
    Eigen::Matrix4d S = Eigen::Matrix4d::Identity();
    if (const auto s = arrays.find(sname); s != arrays.end()) {
      const std::string swhere = npz.string() + ": " + sname;
      S = matrix4(s->second, swhere, false);
      const double sc = S(0, 0);
      Eigen::Matrix4d expect = Eigen::Matrix4d::Identity();
      expect.topLeftCorner<3, 3>() *= sc;
      expect.topRightCorner<3, 1>() = S.topRightCorner<3, 1>();
      if (!(sc > 0) || (S - expect).norm() > 1e-9 * std::max(1.0, S.norm())) {
        throw Error(swhere + " is not a similarity (s·I with s > 0, a translation, 0 0 0 1)");
      }
    }
    if (frame == NeusFrame::Normalized) {
      // x_world = s·x_norm + c: the orientation is unchanged, the centre maps back.
      cam.T_world_camera.translation() =
          (cam.T_world_camera.translation() - S.topRightCorner<3, 1>()) / S(0, 0);
    }
    out.push_back(cam);
  }
  if (out.empty()) throw Error(npz.string() + ": no world_mat_0 entry (not an IDR/NeuS file?)");
  // Entries beyond a gap would be silently dropped: refuse them.
  for (const auto& [name, a] : arrays) {
    (void)a;
    for (const char* prefix : {"world_mat_", "scale_mat_"}) {
      if (name.rfind(prefix, 0) == 0 && name.find("_inv") == std::string::npos) {
        const std::string idx = name.substr(std::string(prefix).size());
        const bool digits = !idx.empty() && idx.size() < 9 &&
                            idx.find_first_not_of("0123456789") == std::string::npos;
        if (!digits || std::stoul(idx) >= out.size()) {
          throw Error(npz.string() + ": " + name + " has no matching world_mat_0 … world_mat_" +
                      std::to_string(out.size() - 1) + " sequence");
        }
      }
    }
  }
  return out;
}

Eigen::Isometry3d camera_world_transform(const std::string& spec) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (spec == "identity") return T;
  if (spec == "aoneus" || spec == "holoocean") {
    // Rows: x_c = −y_s, y_c = −z_s, z_c = x_s.
    T.linear() << 0, -1, 0, 0, 0, -1, 1, 0, 0;
    return T;
  }
  std::string text = spec;
  for (char& ch : text) {
    if (ch == ',') ch = ' ';
  }
  std::istringstream in(text);
  std::vector<double> v;
  std::string tok;
  const std::string what =
      "camera world '" + spec +
      "' must be identity, aoneus, holoocean, or 9, 12 or 16 numbers (a rotation or a rigid "
      "3×4/4×4 matrix, row-major)";
  while (in >> tok) {
    std::size_t used = 0;
    double x = 0;
    try {
      x = std::stod(tok, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    require(used == tok.size() && std::isfinite(x), what);
    v.push_back(x);
  }
  require(v.size() == 9 || v.size() == 12 || v.size() == 16, what);
  const int cols = v.size() == 9 ? 3 : 4;
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) R(r, c) = v[static_cast<std::size_t>(r * cols + c)];
  }
  if (cols == 4) {
    for (int r = 0; r < 3; ++r) T.translation()(r) = v[static_cast<std::size_t>(r * 4 + 3)];
  }
  if (v.size() == 16) {
    require(std::abs(v[12]) + std::abs(v[13]) + std::abs(v[14]) + std::abs(v[15] - 1) < 1e-9,
            "camera world '" + spec + "': a 4×4 matrix must end with the row 0 0 0 1");
  }
  require((R * R.transpose() - Eigen::Matrix3d::Identity()).norm() < 1e-6 && R.determinant() > 0,
          "camera world '" + spec +
              "': the 3×3 part is not a rotation (orthonormal, determinant +1); the camera "
              "world may differ from the sonar's by a rotation and a translation only");
  T.linear() = R;
  return T;
}

CameraIntrinsics intrinsics_from_K(const Eigen::Matrix3d& K, int width, int height) {
  require(std::abs(K(0, 1)) <= 1e-6 * std::abs(K(0, 0)),
          "the camera matrix has skew (K(0,1) != 0), which the camera model does not carry");
  CameraIntrinsics c;
  c.width = width;
  c.height = height;
  c.fx = K(0, 0);
  c.fy = K(1, 1);
  c.cx = K(0, 2);
  c.cy = K(1, 2);
  c.validate();
  return c;
}

}  // namespace sonar3d
