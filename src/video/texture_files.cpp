// `sonar3d texture`: a point cloud coloured from posed camera images on disk.
#include "sonar3d/video/texture_files.hpp"

#include <tbb/task_group.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/core/params.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/video/camera_dataset.hpp"
#include "sonar3d/video/colmap.hpp"

namespace sonar3d {

namespace fs = std::filesystem;

namespace {

bool is_glb_path(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".glb";
}

// The output rule (core/output_dir.hpp): a coloured cloud or mesh sonar3d wrote is replaced only
// with `overwrite`; never a foreign file, an input or a special file.
void check_output(const TextureFilesJob& job) {
  require(!job.output.empty(), "texture: no output file given");
  OutputPolicy policy;
  policy.overwrite = job.overwrite;
  policy.sources = {
      job.cloud,           job.colmap_dir,           job.neus_file, job.images_dir, job.dataset_dir,
      job.navigation_file, job.sonar_navigation_file};
  policy.sources.insert(policy.sources.end(), job.occluders.begin(), job.occluders.end());
  const OutputKind kind = is_glb_path(job.output) ? OutputKind::Gltf
                          : job.is_mesh           ? OutputKind::Mesh
                                                  : OutputKind::PointCloud;
  sonar3d::check_output(job.output, kind, policy, "-o");
}

}  // namespace

void TexturePosesConfig::validate() const {
  TexturePosesConfig copy = *this;
  params::check(copy, "texture");
  (void)camera_world_transform(camera_world);
}

namespace {

// One frame to project: its image file, and its camera unless it comes from the image's size.
struct Frame {
  fs::path file;
  std::optional<CameraIntrinsics> camera;
  std::string camera_name;  // for errors
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();
};

std::vector<Frame> list_frames(const TextureFilesJob& job) {
  std::vector<Frame> frames;
  require(
      int(!job.neus_file.empty()) + int(!job.colmap_dir.empty()) + int(!job.dataset_dir.empty()) ==
          1,
      "texture: give one source of camera poses: a COLMAP model, a NeuS file or a dataset");
  require(job.navigation_file.empty() || !job.dataset_dir.empty(),
          "texture: a navigation file places a dataset's camera frames: give --dataset");
  require(job.sonar_navigation_file.empty() || job.dataset_dir.empty(),
          "texture: --sonar-navigation checks the poses of --neus or --colmap; a dataset's frames "
          "are placed on its navigation (--navigation)");
  require(job.dataset_dir.empty() || job.poses.camera_world == "identity",
          "texture: --camera-world relates the poses of --neus or --colmap to the cloud's world; a "
          "dataset's camera frames are placed on its navigation (T_vehicle_camera)");
  // Poses given in the camera world → the cloud's: T_world_camera = T_cw_world⁻¹ · T_cw_camera.
  const Eigen::Isometry3d world_from_camworld =
      camera_world_transform(job.poses.camera_world).inverse();
  if (!job.dataset_dir.empty()) {
    CameraDataset ds = read_camera_dataset(job.dataset_dir);
    if (!job.navigation_file.empty()) {
      ds.navigation = read_tum(job.navigation_file.string());
      ds.navigation.validate(job.navigation_file.string());
    }
    require(ds.size() > 0, "texture: '" + (job.dataset_dir / "camera" / "frames.csv").string() +
                               "' lists no frame");
    for (std::size_t i = 0; i < ds.size(); ++i) {
      Frame f;
      f.file = ds.image_path(i);
      if (!fs::exists(f.file)) {
        throw Error("camera frame " + std::to_string(ds.frames[i].index) + " ('" +
                    ds.frames[i].file + "') is not in '" + job.dataset_dir.string() + "'");
      }
      f.camera = ds.rig.intrinsics;
      f.camera_name = "camera in '" + (job.dataset_dir / "camera" / "camera.yaml").string() + "'";
      f.T_world_camera = ds.T_world_camera(i);
      frames.push_back(f);
    }
    return frames;
  }
  if (!job.neus_file.empty()) {
    const auto cams = read_neus_cameras(job.neus_file, job.poses.neus_frame);
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(job.images_dir)) {
      std::string ext = e.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(),
                     [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
      if (e.is_regular_file() &&
          (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tif" || ext == ".tiff")) {
        files.push_back(e.path());
      }
    }
    std::sort(files.begin(), files.end());
    if (files.size() != cams.size()) {
      throw Error("'" + job.images_dir.string() + "' holds " + std::to_string(files.size()) +
                  " images but '" + job.neus_file.string() + "' has " +
                  std::to_string(cams.size()) + " cameras (world_mat_i): one image per camera");
    }
    for (std::size_t i = 0; i < cams.size(); ++i) {
      Frame f;
      f.file = files[i];
      f.K = cams[i].K;
      f.T_world_camera = world_from_camworld * cams[i].T_world_camera;
      f.camera_name = job.neus_file.string() + ": world_mat_" + std::to_string(i);
      frames.push_back(f);
    }
    return frames;
  }
  const PosedImages posed = read_colmap_text(job.colmap_dir);
  require(!posed.images.empty(),
          "texture: '" + (job.colmap_dir / "images.txt").string() + "' lists no image");
  check_images_exist(posed, job.images_dir);
  for (const PosedImage& pi : posed.images) {
    Frame f;
    f.file = job.images_dir / pi.name;
    f.camera = posed.cameras.at(pi.camera_id);
    f.camera_name = "camera " + std::to_string(pi.camera_id) + " in '" +
                    (job.colmap_dir / "cameras.txt").string() + "'";
    f.T_world_camera = world_from_camworld * pi.T_world_camera;
    frames.push_back(f);
  }
  return frames;
}

bool is_dark(const Eigen::Vector3f& linear, double level) {
  const auto c = linear_to_srgb8(linear);
  return std::max({c[0], c[1], c[2]}) <= level * 255.0;
}

// The hints that the poses and the cloud disagree (docs/video.md, "Camera world").
void add_consistency_warnings(const TextureFilesJob& job, const std::vector<Frame>& frames,
                              const Trajectory& sonar_nav, TextureFilesResult& r) {
  const TexturePosesConfig& c = job.poses;
  const bool from_file = job.dataset_dir.empty();
  const std::string hint =
      from_file ? (c.camera_world == "identity"
                       ? "; are the poses in another world than the cloud? (--camera-world, e.g. "
                         "aoneus for AONeuS/HoloOcean data; docs/video.md)"
                       : "; is --camera-world " + c.camera_world + " the right relation?")
                : "; check the dataset's T_vehicle_camera and navigation";
  char buf[64];
  if (r.coloured > 0 && static_cast<double>(r.dark) > c.warn_dark_share * r.coloured) {
    std::snprintf(buf, sizeof buf, "%.0f %%", 100.0 * r.dark / r.coloured);
    r.warnings.push_back(std::to_string(r.dark) + " of " + std::to_string(r.coloured) +
                         " coloured points (" + buf +
                         ") took a near-black colour, likely from outside the object" + hint);
  }
  if (!frames.empty() && 2 * r.blind_frames > frames.size()) {
    r.warnings.push_back(std::to_string(r.blind_frames) + " of " + std::to_string(frames.size()) +
                         " images coloured no point" + hint);
  }
  if (sonar_nav.empty()) return;
  const Trajectory& nav = sonar_nav;
  std::vector<double> d;
  for (const Frame& f : frames) {
    double best = std::numeric_limits<double>::infinity();
    for (const Eigen::Isometry3d& T : nav.poses) {
      best = std::min(best, (T.translation() - f.T_world_camera.translation()).norm());
    }
    d.push_back(best);
  }
  if (d.empty()) return;
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  r.median_camera_offset_m = d[d.size() / 2];
  if (r.median_camera_offset_m > c.warn_camera_offset_m) {
    std::snprintf(buf, sizeof buf, "%.2f m", r.median_camera_offset_m);
    r.warnings.push_back(std::string("the camera centres lie a median ") + buf +
                         " from the nearest position of '" + job.sonar_navigation_file.string() +
                         "'" + hint);
  }
}

}  // namespace

TextureFilesResult texture_cloud_files(const TextureFilesJob& job) {
  job.config.validate();
  job.poses.validate();
  require(job.is_mesh || !is_glb_path(job.output),
          "texture: a .glb output needs --mesh (a coloured cloud is written as PLY)");
  check_output(job);
  const std::vector<Frame> frames = list_frames(job);
  Trajectory sonar_nav;
  if (!job.sonar_navigation_file.empty()) {
    sonar_nav = read_tum(job.sonar_navigation_file.string());
    sonar_nav.validate(job.sonar_navigation_file.string());
    require(!sonar_nav.empty(),
            "texture: '" + job.sonar_navigation_file.string() + "' holds no pose");
  }
  PointCloud cloud;
  std::unique_ptr<CloudTexturer> cloud_texturer;
  std::unique_ptr<MeshTexturer> mesh_texturer;
  require(job.is_mesh || job.occluders.empty(), "texture: occluders apply to a mesh only");
  if (job.is_mesh) {
    TriangleMesh occluders;
    for (const fs::path& f : job.occluders) occluders.append(load_mesh(f.string()));
    mesh_texturer =
        std::make_unique<MeshTexturer>(load_mesh(job.cloud.string()), job.mesh, occluders);
  } else {
    cloud = read_ply(job.cloud.string());
    cloud_texturer = std::make_unique<CloudTexturer>(cloud, job.config);
  }
  Progress progress("texture", frames.size(), job.progress);
  TextureFilesResult r;
  r.points = job.is_mesh ? mesh_texturer->mesh().vertices.size() : cloud.size();
  auto texture_frame = [&](std::size_t f, const Frame& fr, const RgbImage& img) {
    CameraIntrinsics cam;
    if (fr.camera) {
      cam = *fr.camera;
    } else {
      try {
        cam = intrinsics_from_K(fr.K, img.width, img.height);
      } catch (const Error& e) {
        throw Error(fr.camera_name + " with image '" + fr.file.string() + "': " + e.what());
      }
    }
    if (img.width != cam.width || img.height != cam.height) {
      throw Error("image '" + fr.file.string() + "' is " + std::to_string(img.width) + "×" +
                  std::to_string(img.height) + " pixels, but its " + fr.camera_name + " is " +
                  std::to_string(cam.width) + "×" + std::to_string(cam.height));
    }
    const CameraView view{cam, fr.T_world_camera, &img};
    const std::size_t seen =
        job.is_mesh ? mesh_texturer->add(view, f) : cloud_texturer->add(view, f);
    if (seen == 0) ++r.blind_frames;
  };
  // The next frame's image is read while this one is textured (both on TBB's threads); a read
  // error is kept and thrown when that frame's turn comes.
  std::optional<RgbImage> next;
  std::exception_ptr next_error;
  auto read_next = [&](std::size_t f) {
    try {
      next = read_rgb_image(frames[f].file);
    } catch (...) {
      next_error = std::current_exception();
    }
  };
  if (!frames.empty()) read_next(0);
  for (std::size_t f = 0; f < frames.size(); ++f) {
    if (next_error) std::rethrow_exception(next_error);
    const RgbImage img = std::move(*next);
    next.reset();
    tbb::task_group reader;
    if (f + 1 < frames.size()) reader.run([&read_next, f] { read_next(f + 1); });
    try {
      texture_frame(f, frames[f], img);
    } catch (...) {
      reader.wait();  // read_next throws nothing
      throw;
    }
    reader.wait();
    ++r.frames;
    progress.add();
  }
  progress.finish();
  if (job.is_mesh) {
    const TexturedMesh tm = mesh_texturer->result();
    r.coloured = tm.coloured();
    r.written = tm.mesh.vertices.size();
    for (std::size_t i = 0; i < tm.color.size(); ++i) {
      if (tm.views[i] > 0 && is_dark(tm.color[i], job.poses.dark_level)) ++r.dark;
    }
    add_consistency_warnings(job, frames, sonar_nav, r);
    if (is_glb_path(job.output)) {
      write_textured_mesh_glb(job.output, tm);
    } else {
      write_textured_mesh_ply(job.output, tm);
    }
    return r;
  }
  const TexturedCloud t = cloud_texturer->result();
  PointCloud out;
  // `views`: the frames that coloured each point (0: none, the colour is then black), so that a
  // black surface seen on video is not taken for an unseen one (sonar3d world, diff). A `views`
  // the input already had is replaced.
  std::size_t views_k = cloud.properties.size();
  for (std::size_t k = 0; k < cloud.properties.size(); ++k) {
    out.properties.push_back({cloud.properties[k].name, {}});
    if (cloud.properties[k].name == "views") views_k = k;
  }
  if (views_k == cloud.properties.size()) out.properties.push_back({"views", {}});
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const bool seen = t.views[i] > 0;
    r.coloured += seen ? 1 : 0;
    if (seen && is_dark(t.color[i], job.poses.dark_level)) ++r.dark;
    if (!seen && job.drop_uncoloured) continue;
    out.points.push_back(cloud.points[i]);
    if (cloud.has_intensity()) out.intensity.push_back(cloud.intensity[i]);
    for (std::size_t k = 0; k < cloud.properties.size(); ++k) {
      if (k != views_k) out.properties[k].values.push_back(cloud.properties[k].values[i]);
    }
    out.properties[views_k].values.push_back(static_cast<float>(t.views[i]));
    out.color.push_back(seen ? linear_to_srgb8(t.color[i]) : std::array<std::uint8_t, 3>{0, 0, 0});
  }
  r.written = out.size();
  add_consistency_warnings(job, frames, sonar_nav, r);
  write_ply(job.output.string(), out);
  return r;
}

}  // namespace sonar3d
