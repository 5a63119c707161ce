#pragma once
// Camera poses from IDR/NeuS `cameras_*.npz` files (docs/video.md, "IDR/NeuS cameras"):
//   world_mat_i = K·[R | t] (3×4, or 4×4 with a last row 0 0 0 1): world point → pixel, OpenCV's
//                 camera frame (+z forward, +x right, +y down), pixel (0, 0) the centre of the
//                 top-left pixel (as OpenCV, which IDR/NeuS use to decompose and project);
//   scale_mat_i = 4×4 similarity (scale s, translation c): normalized point → world point,
//                 x_world = s·x_norm + c; NeuS reconstructs, and exports its meshes, in the
//                 normalized frame (the unit sphere around the object).
// Decomposition as OpenCV's decomposeProjectionMatrix, which NeuS's load_K_Rt_from_P calls:
// P[:, :3] = K·R by an RQ decomposition with K's diagonal positive, K divided by K(2,2), the
// camera centre C the right null vector of P; T_world_camera = (Rᵀ, C).
#include <Eigen/Geometry>
#include <filesystem>
#include <string>
#include <vector>

#include "sonar3d/video/camera.hpp"

namespace sonar3d {

enum class NeusFrame {
  World,       // the original world frame: world_mat as given
  Normalized,  // NeuS's normalized frame: x_norm = (x_world − c)/s by scale_mat
};

struct NeusCamera {
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();                   // K(2,2) = 1, zero skew
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();  // in the chosen frame
};

// P = K·R·[I | −C] → K (K(2,2) = 1, positive diagonal) and T_world_camera = (Rᵀ, C). Throws
// Error when P[:, :3] is singular or not finite.
void decompose_projection(const Eigen::Matrix<double, 3, 4>& P, Eigen::Matrix3d* K,
                          Eigen::Isometry3d* T_world_camera);

// Reads world_mat_0 … world_mat_{n−1} (consecutive from 0) and scale_mat_i (identity when
// absent; it must be a similarity: s·I with s > 0 and a translation). Errors name the file and
// entry.
std::vector<NeusCamera> read_neus_cameras(const std::filesystem::path& npz,
                                          NeusFrame frame = NeusFrame::World);

// How the poses' world (a NeuS or COLMAP reconstruction's "camera world") relates to the cloud's
// world (the sonar's navigation frame), docs/video.md "Camera world": returns T_cameraworld_world,
// p_cameraworld = T·p_world. `spec` is
//   "identity"             the two worlds are one (the default);
//   "aoneus", "holoocean"  AONeuS's convention for HoloOcean data, (x, y, z)_camera-world =
//                          (−y, −z, x)_sonar-world (a rotation, no translation);
//   9 numbers              a rotation matrix, row-major;
//   12 or 16 numbers       a rigid 3×4 or 4×4 matrix, row-major (a 4×4 ends with 0 0 0 1);
// numbers separated by commas and/or spaces. Throws Error when the matrix is not a rotation
// (orthonormal within 1e-6, determinant +1) or the text none of these.
Eigen::Isometry3d camera_world_transform(const std::string& spec);

// Pinhole intrinsics from K for an image of width × height (no distortion: IDR/NeuS images are
// undistorted). Throws when K has skew (|K(0,1)| > 1e-6·fx).
CameraIntrinsics intrinsics_from_K(const Eigen::Matrix3d& K, int width, int height);

}  // namespace sonar3d
