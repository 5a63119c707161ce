#include "sonar3d/sim/simulation.hpp"

#include <chrono>
#include <cmath>
#include <fstream>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/core/reference_objects.hpp"
#include "sonar3d/core/units.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/io/yaml_config.hpp"
#include "sonar3d/sim/terrain.hpp"
#include "sonar3d/sim/trajectory_gen.hpp"

namespace fs = std::filesystem;

namespace sonar3d {
namespace {

TriangleMesh load_primitive(const YAML::Node& n, const std::string& file, const std::string& ctx) {
  const std::string type = yaml::get_string(n, "type", "", file, ctx);
  if (type == "sphere") {
    yaml::check_keys(n, {"type", "radius"}, file, ctx);
    const double r = yaml::get_double(n, "radius", file, ctx);
    require_positive(r, (ctx + ".radius").c_str(), "m");
    return make_sphere(r);
  }
  if (type == "box") {
    yaml::check_keys(n, {"type", "size"}, file, ctx);
    const auto s = yaml::get_vector(n, "size", 3, file, ctx);
    for (double v : s) require_positive(v, (ctx + ".size").c_str(), "m");
    return make_box(s[0], s[1], s[2]);
  }
  if (type == "cylinder") {
    yaml::check_keys(n, {"type", "radius", "height"}, file, ctx);
    const double r = yaml::get_double(n, "radius", file, ctx);
    const double h = yaml::get_double(n, "height", file, ctx);
    require_positive(r, (ctx + ".radius").c_str(), "m");
    require_positive(h, (ctx + ".height").c_str(), "m");
    return make_cylinder(r, h);
  }
  if (type == "plane") {
    yaml::check_keys(n, {"type", "size"}, file, ctx);
    const auto s = yaml::get_vector(n, "size", 2, file, ctx);
    for (double v : s) require_positive(v, (ctx + ".size").c_str(), "m");
    return make_plane(s[0], s[1]);
  }
  if (type == "terrain") {
    yaml::check_keys(n,
                     {"type", "size", "cell", "relief", "wavelength", "trenches", "trench_depth",
                      "trench_width", "rocks", "rock_radius", "seed"},
                     file, ctx);
    TerrainConfig t;
    const auto s = yaml::get_vector(n, "size", 2, file, ctx);
    t.size = {s[0], s[1]};
    t.cell_m = yaml::get_double(n, "cell", t.cell_m, file, ctx);
    t.relief_m = yaml::get_double(n, "relief", t.relief_m, file, ctx);
    t.wavelength_m = yaml::get_double(n, "wavelength", t.wavelength_m, file, ctx);
    t.trenches = yaml::get_int(n, "trenches", t.trenches, file, ctx);
    t.trench_depth_m = yaml::get_double(n, "trench_depth", t.trench_depth_m, file, ctx);
    t.trench_width_m = yaml::get_double(n, "trench_width", t.trench_width_m, file, ctx);
    t.rocks = yaml::get_int(n, "rocks", t.rocks, file, ctx);
    t.rock_radius_m = yaml::get_double(n, "rock_radius", t.rock_radius_m, file, ctx);
    t.seed = static_cast<unsigned long long>(yaml::get_int(n, "seed", 1, file, ctx));
    try {
      return Terrain(t).mesh();
    } catch (const Error& e) {
      throw Error(yaml::where(file, n, ctx) + ": " + e.what());
    }
  }
  throw Error(yaml::where(file, n, ctx + ".type") + ": unknown primitive '" + printable(type) +
              "' (sphere, box, cylinder, plane, terrain)");
}

// A pipeline laid from `from` to `to` (world points on the seabed, m), a cylinder of `radius`
// sunk by `burial` of its diameter below the line joining them (0: lying on it, 0.5: half
// buried).
TriangleMesh load_pipeline(const YAML::Node& n, const std::string& file, const std::string& ctx) {
  yaml::check_keys(n, {"from", "to", "radius", "burial"}, file, ctx);
  const auto a = yaml::get_vector(n, "from", 3, file, ctx);
  const auto b = yaml::get_vector(n, "to", 3, file, ctx);
  const double r = yaml::get_double(n, "radius", file, ctx);
  const double burial = yaml::get_double(n, "burial", 0.5, file, ctx);
  require_positive(r, (ctx + ".radius").c_str(), "m");
  if (!(burial >= 0 && burial < 1)) {
    throw Error(yaml::where(file, n["burial"], ctx + ".burial") +
                ": must lie in [0, 1) (the buried fraction of the diameter)");
  }
  const Eigen::Vector3d from(a[0], a[1], a[2]), to(b[0], b[1], b[2]);
  const double length = (to - from).norm();
  if (!(length > 1e-6) || !std::isfinite(length)) {
    throw Error(yaml::where(file, n, ctx) + ": 'from' and 'to' must be distinct finite points");
  }
  TriangleMesh m = make_cylinder(r, length);  // along +z from the origin
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() =
      Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), (to - from) / length).matrix();
  T.translation() = from + Eigen::Vector3d(0, 0, r - burial * 2 * r);
  m.transform(T);
  return m;
}

Trajectory load_segment(const YAML::Node& n, const std::string& file, const std::string& ctx,
                        double t0, double period, const fs::path& base) {
  const std::string type = yaml::get_string(n, "type", "", file, ctx);
  if (type == "straight") {
    yaml::check_keys(n, {"type", "start", "end", "spacing", "rpy_deg", "period"}, file, ctx);
    const auto a = yaml::get_vector(n, "start", 3, file, ctx);
    const auto b = yaml::get_vector(n, "end", 3, file, ctx);
    const double spacing = yaml::get_double(n, "spacing", file, ctx);
    std::vector<double> rpy{0, 0, 0};
    if (n["rpy_deg"]) rpy = yaml::get_vector(n, "rpy_deg", 3, file, ctx);
    const Eigen::Matrix3d R =
        yaml::pose_from_rpy(Eigen::Vector3d::Zero(), rpy[0] * kDeg, rpy[1] * kDeg, rpy[2] * kDeg)
            .linear();
    try {
      return straight_pass(Eigen::Vector3d(a[0], a[1], a[2]), Eigen::Vector3d(b[0], b[1], b[2]),
                           spacing, R, t0, period);
    } catch (const Error& e) {
      throw Error(yaml::where(file, n, ctx) + ": " + e.what());
    }
  }
  if (type == "orbit") {
    yaml::check_keys(n, {"type", "center", "radius", "count", "start_deg", "sweep_deg", "period"},
                     file, ctx);
    const auto c = yaml::get_vector(n, "center", 3, file, ctx);
    try {
      return orbit(Eigen::Vector3d(c[0], c[1], c[2]), yaml::get_double(n, "radius", file, ctx),
                   yaml::get_int(n, "count", 0, file, ctx),
                   yaml::get_double(n, "start_deg", 0.0, file, ctx) * kDeg,
                   yaml::get_double(n, "sweep_deg", 360.0, file, ctx) * kDeg, t0, period);
    } catch (const Error& e) {
      throw Error(yaml::where(file, n, ctx) + ": " + e.what());
    }
  }
  if (type == "lawnmower") {
    yaml::check_keys(
        n,
        {"type", "x", "y", "z", "line_spacing", "spacing", "heading_deg", "turn_radius", "period"},
        file, ctx);
    const auto x = yaml::get_vector(n, "x", 2, file, ctx);
    const auto y = yaml::get_vector(n, "y", 2, file, ctx);
    LawnmowerConfig c;
    c.x0 = x[0];
    c.x1 = x[1];
    c.y0 = y[0];
    c.y1 = y[1];
    c.z = yaml::get_double(n, "z", file, ctx);
    c.line_spacing = yaml::get_double(n, "line_spacing", file, ctx);
    c.spacing = yaml::get_double(n, "spacing", file, ctx);
    c.heading = yaml::get_double(n, "heading_deg", 0.0, file, ctx) * kDeg;
    c.turn_radius = yaml::get_double(n, "turn_radius", 0.0, file, ctx);
    try {
      return lawnmower(c, t0, period);
    } catch (const Error& e) {
      throw Error(yaml::where(file, n, ctx) + ": " + e.what());
    }
  }
  if (type == "tum") {
    yaml::check_keys(n, {"type", "file", "period"}, file, ctx);
    fs::path p = yaml::get_string(n, "file", "", file, ctx);
    if (p.is_relative()) p = base / p;
    Trajectory tum = read_tum(p.string());
    tum.validate(p.string());
    if (tum.empty()) throw Error(p.string() + ": the trajectory has no pose");
    // Keep the file's spacing in time, shifted to start at t0.
    const double shift = t0 - tum.times.front();
    for (double& t : tum.times) t += shift;
    return tum;
  }
  throw Error(yaml::where(file, n, ctx + ".type") + ": unknown trajectory type '" +
              printable(type) + "' (straight, orbit, lawnmower, tum)");
}

}  // namespace

void SimulateConfig::validate() const {
  params::check(*this, "simulate");
  require(!seed || *seed == std::floor(*seed),
          "simulate: seed must be a whole number, got " + params::format_number(*seed));
}

SimulationSetup load_simulation_setup(const std::string& path) {
  SimulationSetup setup;
  setup.source = path;
  const fs::path base = fs::path(path).parent_path();
  YAML::Node root = yaml::load_file(path);
  if (!root.IsMap()) throw Error(path + ": expected a mapping at the top level");
  yaml::check_keys(root,
                   {"sensor", "simulation", "objects", "trajectory", "noise", "seed",
                    "navigation_error", "camera"},
                   path);
  if (!root["sensor"]) throw Error(path + ": required key 'sensor' is missing");
  setup.spec = yaml::parse_sonar_spec(root["sensor"], path, "sensor");
  setup.seed = static_cast<unsigned long long>(yaml::get_int(root, "seed", 1, path));

  if (const YAML::Node s = root["simulation"]) {
    yaml::check_keys(s, {"elevation_step_deg", "rays_per_beam", "jitter", "gain", "num_threads"},
                     path, "simulation");
    auto& c = setup.simulator;
    c.elevation_step_rad =
        yaml::get_double(s, "elevation_step_deg", c.elevation_step_rad / kDeg, path, "simulation") *
        kDeg;
    c.rays_per_beam = yaml::get_int(s, "rays_per_beam", c.rays_per_beam, path, "simulation");
    c.jitter = yaml::get_bool(s, "jitter", c.jitter, path, "simulation");
    c.gain = yaml::get_double(s, "gain", c.gain, path, "simulation");
    c.num_threads = yaml::get_int(s, "num_threads", c.num_threads, path, "simulation");
    try {
      c.validate();
    } catch (const Error& e) {
      throw Error(yaml::where(path, s, "simulation") + ": " + e.what());
    }
  }

  const YAML::Node objs = root["objects"];
  if (!objs || !objs.IsSequence() || objs.size() == 0) {
    throw Error(path + ": the scene is empty: 'objects' must list at least one object");
  }
  for (std::size_t i = 0; i < objs.size(); ++i) {
    const YAML::Node o = objs[i];
    const std::string ctx = "objects[" + std::to_string(i) + "]";
    yaml::check_keys(o,
                     {"name", "reference", "mesh", "primitive", "pipeline", "pose", "scale",
                      "reflectivity", "kind", "color"},
                     path, ctx);
    SceneObject obj;
    obj.name = yaml::get_string(o, "name", "object" + std::to_string(i), path, ctx);
    const int sources = (o["reference"] ? 1 : 0) + (o["mesh"] ? 1 : 0) + (o["primitive"] ? 1 : 0) +
                        (o["pipeline"] ? 1 : 0);
    if (sources != 1) {
      throw Error(yaml::where(path, o, ctx) +
                  ": give exactly one of 'reference', 'mesh', 'primitive' or 'pipeline'");
    }
    if (o["pipeline"] && (o["pose"] || o["scale"])) {
      throw Error(yaml::where(path, o, ctx) +
                  ": a pipeline is placed by its 'from' and 'to' points: no 'pose' or 'scale'");
    }
    try {
      if (o["reference"]) {
        obj.mesh_world = make_reference_object(yaml::get_string(o, "reference", "", path, ctx));
      } else if (o["mesh"]) {
        fs::path mp = yaml::get_string(o, "mesh", "", path, ctx);
        if (mp.is_relative()) mp = base / mp;
        obj.mesh_world = load_mesh(mp.string());
      } else if (o["pipeline"]) {
        obj.mesh_world = load_pipeline(o["pipeline"], path, ctx + ".pipeline");
        obj.kind = ObjectKind::Pipeline;
      } else {
        obj.mesh_world = load_primitive(o["primitive"], path, ctx + ".primitive");
        if (yaml::get_string(o["primitive"], "type", "", path, ctx + ".primitive") == "terrain") {
          obj.kind = ObjectKind::Terrain;
        }
      }
      if (o["kind"]) {  // e.g. a seabed from a mesh file
        obj.kind = object_kind_from_string(yaml::get_string(o, "kind", "", path, ctx));
      }
    } catch (const Error& e) {
      const std::string msg = e.what();
      throw Error(msg.rfind(path, 0) == 0 ? msg : yaml::where(path, o, ctx) + ": " + msg);
    }
    const double scale = yaml::get_double(o, "scale", 1.0, path, ctx);
    if (!(scale > 0)) throw Error(yaml::where(path, o["scale"], ctx + ".scale") + ": must be > 0");
    for (auto& v : obj.mesh_world.vertices) v *= static_cast<float>(scale);
    if (o["pose"]) obj.mesh_world.transform(yaml::get_pose(o["pose"], path, ctx + ".pose"));
    obj.reflectivity = yaml::get_double(o, "reflectivity", 0.5, path, ctx);
    if (!(obj.reflectivity >= 0 && obj.reflectivity <= 1)) {
      throw Error(yaml::where(path, o["reflectivity"], ctx + ".reflectivity") +
                  ": must lie in [0, 1]");
    }
    if (o["color"]) {
      const auto c = yaml::get_vector(o, "color", 3, path, ctx);
      for (double v : c) {
        if (!(v >= 0 && v <= 1)) {
          throw Error(yaml::where(path, o["color"], ctx + ".color") +
                      ": each of r, g, b must lie in [0, 1]");
        }
      }
      obj.color = Eigen::Vector3d(c[0], c[1], c[2]).cast<float>();
    }
    for (const auto& other : setup.scene.objects) {
      if (other.name == obj.name) {
        throw Error(yaml::where(path, o, ctx + ".name") + ": duplicate object name '" +
                    printable(obj.name) + "'");
      }
    }
    setup.scene.objects.push_back(std::move(obj));
  }
  if (setup.scene.empty()) throw Error(path + ": the scene is empty: no object has triangles");

  const YAML::Node tr = root["trajectory"];
  if (!tr) throw Error(path + ": required key 'trajectory' is missing");
  yaml::check_keys(tr,
                   {"period", "segments", "type", "start", "end", "spacing", "rpy_deg", "center",
                    "radius", "count", "start_deg", "sweep_deg", "x", "y", "z", "line_spacing",
                    "heading_deg", "turn_radius", "file"},
                   path, "trajectory");
  const double period = yaml::get_double(tr, "period", 0.1, path, "trajectory");
  require_positive(period, "trajectory.period", "s");
  std::vector<std::pair<YAML::Node, std::string>> segs;
  if (tr["segments"]) {
    if (!tr["segments"].IsSequence() || tr["segments"].size() == 0) {
      throw Error(yaml::where(path, tr["segments"], "trajectory.segments") +
                  ": expected a non-empty list");
    }
    for (std::size_t i = 0; i < tr["segments"].size(); ++i) {
      const YAML::Node seg = tr["segments"][i];
      const std::string ctx = "trajectory.segments[" + std::to_string(i) + "]";
      if (seg.IsMap() && seg["period"]) {
        throw Error(yaml::where(path, seg["period"], ctx + ".period") +
                    ": the frame period is set once, as trajectory.period");
      }
      segs.emplace_back(seg, ctx);
    }
  } else {
    segs.emplace_back(tr, "trajectory");  // a single segment; its 'period' is read above
  }
  double t0 = 0.0;
  for (const auto& [node, ctx] : segs) {
    const Trajectory seg = load_segment(node, path, ctx, t0, period, base);
    if (static_cast<double>(setup.T_world_vehicle.size() + seg.size()) > limits::kMaxFrames) {
      throw Error(yaml::where(path, node, ctx) + ": the trajectory has more than " +
                  std::to_string(static_cast<long long>(limits::kMaxFrames)) +
                  " frames; increase the spacing");
    }
    for (std::size_t k = 0; k < seg.size(); ++k) {
      setup.T_world_vehicle.push_back(seg.times[k], seg.poses[k]);
    }
    t0 = setup.T_world_vehicle.times.back() + period;
  }
  setup.T_world_vehicle.validate(path + ": trajectory");

  if (const YAML::Node n = root["navigation_error"]) {
    const std::string c = "navigation_error";
    yaml::check_keys(n, {"velocity_scale", "bias_walk", "heading_bias_deg", "depth_offset"}, path,
                     c);
    DeadReckoningConfig dr;
    dr.velocity_scale_error =
        yaml::get_double(n, "velocity_scale", dr.velocity_scale_error, path, c);
    dr.velocity_bias_walk = yaml::get_double(n, "bias_walk", dr.velocity_bias_walk, path, c);
    dr.heading_bias_deg = yaml::get_double(n, "heading_bias_deg", dr.heading_bias_deg, path, c);
    dr.depth_offset_m = yaml::get_double(n, "depth_offset", dr.depth_offset_m, path, c);
    try {
      dr.validate();
    } catch (const Error& e) {
      throw Error(yaml::where(path, n, c) + ": " + e.what());
    }
    setup.navigation_error = dr;
  }
  if (const YAML::Node n = root["camera"]) {
    SimulatedCamera cam;
    cam.rig = parse_camera_rig(n, path, "camera", {"rate_hz", "ambient", "attenuation_per_m"});
    cam.rate_hz = yaml::get_double(n, "rate_hz", cam.rate_hz, path, "camera");
    cam.render.ambient = yaml::get_double(n, "ambient", cam.render.ambient, path, "camera");
    cam.render.attenuation_per_m =
        yaml::get_double(n, "attenuation_per_m", cam.render.attenuation_per_m, path, "camera");
    if (!(cam.rate_hz > 0 && cam.rate_hz <= 1000)) {
      throw Error(yaml::where(path, n, "camera.rate_hz") + ": must be within (0, 1000] Hz");
    }
    const double span = setup.T_world_vehicle.times.back() - setup.T_world_vehicle.times.front();
    if (span * cam.rate_hz > 1e6) {
      throw Error(yaml::where(path, n, "camera.rate_hz") + ": " + std::to_string(span) +
                  " s of trajectory at this rate is more than a million camera frames");
    }
    try {
      cam.render.validate();
    } catch (const Error& e) {
      throw Error(yaml::where(path, n, "camera") + ": " + e.what());
    }
    setup.camera = cam;
  }
  if (const YAML::Node n = root["noise"]) {
    yaml::check_keys(n, {"model", "scale", "stripes", "mean", "std"}, path, "noise");
    const std::string model = yaml::get_string(n, "model", "none", path, "noise");
    auto& nc = setup.noise;
    nc.scale = yaml::get_double(n, "scale", 1.0, path, "noise");
    if (!(nc.scale >= 0)) throw Error(yaml::where(path, n, "noise.scale") + ": must be >= 0");
    if (model == "none") {
      nc.kind = NoiseModelConfig::Kind::None;
    } else if (model == "stripes") {
      nc.kind = NoiseModelConfig::Kind::Stripes;
      if (const YAML::Node s = n["stripes"]) {
        const std::string c = "noise.stripes";
        yaml::check_keys(s,
                         {"count", "width_deg", "stripe_mean", "stripe_std", "floor_mean",
                          "floor_std", "range_decay"},
                         path, c);
        auto& st = nc.stripes;
        st.count = yaml::get_int(s, "count", st.count, path, c);
        st.width_deg = yaml::get_double(s, "width_deg", st.width_deg, path, c);
        st.stripe_mean = yaml::get_double(s, "stripe_mean", st.stripe_mean, path, c);
        st.stripe_std = yaml::get_double(s, "stripe_std", st.stripe_std, path, c);
        st.floor_mean = yaml::get_double(s, "floor_mean", st.floor_mean, path, c);
        st.floor_std = yaml::get_double(s, "floor_std", st.floor_std, path, c);
        st.range_decay = yaml::get_double(s, "range_decay", st.range_decay, path, c);
        try {
          st.validate();
        } catch (const Error& e) {
          throw Error(yaml::where(path, s, c) + ": " + e.what());
        }
      }
    } else if (model == "images") {
      nc.kind = NoiseModelConfig::Kind::Images;
      fs::path m = yaml::get_string(n, "mean", "", path, "noise");
      fs::path s = yaml::get_string(n, "std", "", path, "noise");
      if (m.empty() || s.empty()) {
        throw Error(yaml::where(path, n, "noise") + ": model 'images' needs 'mean' and 'std'");
      }
      nc.mean_path = (m.is_relative() ? base / m : m).string();
      nc.std_path = (s.is_relative() ? base / s : s).string();
      noise_images(setup);  // check the files now, not after the first frames
    } else {
      throw Error(yaml::where(path, n["model"], "noise.model") + ": unknown noise model '" +
                  printable(model) + "' (none, stripes, images)");
    }
  }
  // Fails early on settings the simulator refuses (e.g. a step wider than the aperture).
  Simulator check(setup.scene, setup.spec, setup.simulator);
  return setup;
}

std::optional<NoiseImages> noise_images(const SimulationSetup& setup) {
  const auto& nc = setup.noise;
  std::optional<NoiseImages> out;
  if (nc.kind == NoiseModelConfig::Kind::Stripes) {
    out = stripe_noise_images(setup.spec, nc.stripes);
  } else if (nc.kind == NoiseModelConfig::Kind::Images) {
    NoiseImages n{read_float_image(nc.mean_path), read_float_image(nc.std_path)};
    for (const auto* im : {&n.mean, &n.std}) {
      if (im->rows != setup.spec.range_bins || im->cols != setup.spec.beams()) {
        throw Error("noise image is " + std::to_string(im->rows) + "×" + std::to_string(im->cols) +
                    " but the sonar has " + std::to_string(setup.spec.range_bins) +
                    " range bins × " + std::to_string(setup.spec.beams()) + " beams (" +
                    nc.mean_path + ")");
      }
    }
    for (float v : n.std.data) {
      if (v < 0) throw Error("noise std image '" + nc.std_path + "' holds a negative value");
    }
    out = std::move(n);
  }
  if (out && nc.scale != 1.0) {
    for (auto& v : out->mean.data) v *= static_cast<float>(nc.scale);
    for (auto& v : out->std.data) v *= static_cast<float>(nc.scale);
  }
  return out;
}

namespace {

// The camera's images over the trajectory's span at rate_hz, rendered at the true poses.
void simulate_camera_frames(const SimulationSetup& setup, const fs::path& camera_dir,
                            bool progress) {
  const SimulatedCamera& cam = *setup.camera;
  const Trajectory& traj = setup.T_world_vehicle;
  const CameraRenderer renderer(setup.scene, cam.render);
  CameraFramesWriter writer(camera_dir, cam.rig);
  const double t0 = traj.times.front(), span = traj.times.back() - t0;
  const auto count = static_cast<std::size_t>(std::floor(span * cam.rate_hz + 1e-9)) + 1;
  Progress bar("camera", count, progress);
  for (std::size_t k = 0; k < count; ++k) {
    const double t = std::min(t0 + static_cast<double>(k) / cam.rate_hz, traj.times.back());
    const Eigen::Isometry3d T_world_camera = traj.interpolate(t) * cam.rig.T_vehicle_camera;
    writer.add(t, renderer.render(cam.rig.intrinsics, T_world_camera));
    bar.add();
  }
  bar.finish();
  writer.finish();
}

}  // namespace

SimulationStats simulate_dataset(const SimulationSetup& setup, const fs::path& out, bool progress) {
  const auto t_start = std::chrono::steady_clock::now();
  const Simulator sim(setup.scene, setup.spec, setup.simulator);
  const std::optional<NoiseImages> noise = noise_images(setup);
  DatasetWriter writer(out, setup.spec);
  const Trajectory& traj = setup.T_world_vehicle;
  Progress bar("simulate", traj.size(), progress);
  for (std::size_t k = 0; k < traj.size(); ++k) {
    const Eigen::Isometry3d T_world_sonar = traj.poses[k] * setup.spec.T_vehicle_sonar;
    const unsigned long long frame_seed = setup.seed * 0x100000001B3ull + k;
    SonarImage img = sim.render(T_world_sonar, frame_seed);
    if (noise) {
      std::mt19937_64 rng(frame_seed ^ 0x5DEECE66Dull);
      add_noise(img, *noise, rng);
    }
    img.timestamp = traj.times[k];
    writer.add_frame(img);
    bar.add();
  }
  bar.finish();
  // The navigation the vehicle logs: the true one, or dead reckoning drifting from it.
  writer.set_navigation(
      setup.navigation_error ? dead_reckoning(traj, *setup.navigation_error, setup.seed) : traj);
  if (noise) writer.set_noise(*noise);
  if (setup.camera) simulate_camera_frames(setup, writer.part_dir("camera"), progress);

  // Ground truth: every object's world-frame mesh and a scene.yaml that lists them.
  const fs::path truth = writer.truth_dir();
  YAML::Emitter y;
  y << YAML::BeginMap << YAML::Key << "source" << YAML::Value << setup.source;
  y << YAML::Key << "frame" << YAML::Value << "world";
  y << YAML::Key << "objects" << YAML::Value << YAML::BeginSeq;
  for (const auto& o : setup.scene.objects) {
    const std::string file = o.name + ".ply";
    save_mesh((truth / file).string(), o.mesh_world);
    y << YAML::BeginMap << YAML::Key << "name" << YAML::Value << o.name;
    y << YAML::Key << "mesh" << YAML::Value << file;
    y << YAML::Key << "reflectivity" << YAML::Value << o.reflectivity;
    y << YAML::Key << "kind" << YAML::Value << to_string(o.kind);
    y << YAML::Key << "color" << YAML::Value << YAML::Flow << YAML::BeginSeq << o.color.x()
      << o.color.y() << o.color.z() << YAML::EndSeq << YAML::EndMap;
  }
  y << YAML::EndSeq << YAML::EndMap;
  write_text_file((truth / "scene.yaml").string(), std::string(y.c_str()) + "\n");
  fs::copy_file(setup.source, truth / "source_scene.yaml", fs::copy_options::overwrite_existing);
  write_tum((truth / "navigation.tum").string(), traj);  // the true vehicle trajectory
  writer.commit();

  SimulationStats st;
  st.frames = traj.size();
  st.rays = traj.size() * sim.rays_per_image();
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return st;
}

}  // namespace sonar3d
