// One sweep point: build the inspection from its parameters, simulate, reconstruct, evaluate.
#include <chrono>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "plan_internal.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/reference_objects.hpp"
#include "sonar3d/core/units.hpp"
#include "sonar3d/eval/per_object.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/io/params_yaml.hpp"
#include "sonar3d/plan/sweep.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/recon/reconstruct.hpp"
#include "sonar3d/sim/simulation.hpp"
#include "sonar3d/sim/trajectory_gen.hpp"

namespace fs = std::filesystem;

namespace sonar3d {
namespace {

double num(const std::map<std::string, SweepValue>& p, const std::string& k) {
  return std::get<double>(p.at(k));
}
std::string str(const std::map<std::string, SweepValue>& p, const std::string& k) {
  return std::get<std::string>(p.at(k));
}

std::uint64_t directory_bytes(const fs::path& dir) {
  std::uint64_t n = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.is_regular_file()) n += e.file_size();
  }
  return n;
}

}  // namespace

TriangleMesh plan_object_mesh(const std::string& object, const fs::path& sweep_dir) {
  const auto names = reference_object_names();
  if (std::find(names.begin(), names.end(), object) != names.end()) {
    return make_reference_object(object);
  }
  fs::path p = object;
  if (p.is_relative()) p = sweep_dir / p;
  return load_mesh(p.string());
}

SimulationSetup plan_setup(const Sweep& sweep, const std::map<std::string, SweepValue>& p,
                           const fs::path& sweep_dir) {
  SimulationSetup setup;
  setup.source = sweep.source;
  setup.seed = sweep.seed;
  SceneObject obj;
  obj.name = fs::path(str(p, "object")).stem().string();
  obj.mesh_world = plan_object_mesh(str(p, "object"), sweep_dir);
  obj.reflectivity = 0.8;
  const Eigen::AlignedBox3f box = obj.mesh_world.bounding_box();
  // The object stands at the origin; its horizontal half-extent sets the range window.
  const double half = 0.5 * std::max(box.sizes().x(), box.sizes().y());
  setup.scene.objects.push_back(obj);

  const double standoff = num(p, "standoff_m");
  const double aperture = num(p, "aperture_deg") * kDeg;
  SonarSpec& s = setup.spec;
  s.name = "plan";
  const double fov = num(p, "fov_deg") * kDeg;
  // Counts from ratios are checked before they become integers: a resolution of 1e-9 would
  // otherwise overflow int and silently become 1 beam, 1 bin or 8 frames (limits.hpp).
  const long long beams = limits::checked_count(
      std::round(num(p, "fov_deg") / num(p, "bearing_res_deg")), 1, limits::kMaxBeams,
      "fov_deg / bearing_res_deg (beams)", "use a coarser bearing_res_deg");
  s.set_uniform_bearings(fov, static_cast<int>(beams));
  s.vertical_aperture_rad = aperture;
  s.r_min = std::max(0.1, standoff - half - 0.5);
  s.r_max = standoff + half + 1.0;
  s.range_bins = static_cast<int>(limits::checked_count(
      std::ceil((s.r_max - s.r_min) / num(p, "range_res_m")), 1, limits::kMaxRangeBins,
      "range window / range_res_m (range bins)", "use a coarser range_res_m"));
  s.r_max = s.r_min + s.range_bins * num(p, "range_res_m");
  setup.simulator.elevation_step_rad = std::min(sweep.elevation_step_deg * kDeg, aperture);
  setup.simulator.num_threads = 1;

  const double spacing = num(p, "spacing_m");
  const std::string path = str(p, "path");
  if (standoff <= half) {
    throw Error("stand-off " + std::to_string(standoff) + " m puts the sonar inside the object");
  }
  if (path == "vertical") {
    // The thesis' vertical inspection: the sonar looks horizontally at the object and moves
    // along its own z axis (the direction of uncertainty) past the object's whole height, by
    // enough that every surface point is bracketed: the elevation arc above the object's top
    // (range up to standoff + half) is carved only by frames that see it with the top itself out
    // of the aperture, i.e. up to 2·r·tan(A_v/2) above the top (and likewise below the base).
    // Shorter passes leave those arcs as outliers (measured: 4–10 % of the cloud at 10°).
    const double reach = std::min(2.0, 2.0 * (standoff + half) * std::tan(0.5 * aperture));
    setup.T_world_vehicle = straight_pass(Eigen::Vector3d(-standoff, 0, box.min().z() - reach),
                                          Eigen::Vector3d(-standoff, 0, box.max().z() + reach),
                                          spacing, Eigen::Matrix3d::Identity(), 0.0, 0.1);
  } else {
    const double circumference = 2 * M_PI * standoff;
    const int count = static_cast<int>(std::max<long long>(
        8, limits::checked_count(std::ceil(circumference / spacing), 1, limits::kMaxFrames,
                                 "orbit circumference / spacing_m (frames)",
                                 "use a larger spacing_m")));
    setup.T_world_vehicle =
        orbit(Eigen::Vector3d(0, 0, box.center().z()), standoff, count, M_PI, 2 * M_PI, 0.0, 0.1);
  }
  if (std::holds_alternative<double>(p.at("snr_db"))) {
    setup.noise.kind = NoiseModelConfig::Kind::Stripes;
    setup.noise.scale = plan_noise_scale(setup, num(p, "snr_db"));
  }
  return setup;
}

double plan_noise_scale(const SimulationSetup& setup, double snr_db) {
  // SNR_dB = 20·log10(S / σ̄): S is the mean intensity of the pixels that hold a return in a
  // noise-free frame from the middle of the trajectory, σ̄ the mean noise standard deviation of
  // the stripe model over the image. The stripe model is scaled to reach the requested SNR.
  const Simulator sim(setup.scene, setup.spec, setup.simulator);
  const std::size_t mid = setup.T_world_vehicle.size() / 2;
  const SonarImage img =
      sim.render(setup.T_world_vehicle.poses[mid] * setup.spec.T_vehicle_sonar, setup.seed);
  double sum = 0;
  std::size_t n = 0;
  for (float v : img.data) {
    if (v > 0) {
      sum += v;
      ++n;
    }
  }
  if (n == 0) throw Error("SNR calibration: the middle frame sees nothing of the object");
  const NoiseImages model = stripe_noise_images(setup.spec, setup.noise.stripes);
  double sigma = 0;
  for (float v : model.std.data) sigma += v;
  sigma /= static_cast<double>(model.std.data.size());
  return (sum / n) / std::pow(10.0, snr_db / 20.0) / sigma;
}

ReconstructConfig plan_reconstruct_config(const SimulationSetup& setup,
                                          const std::map<std::string, SweepValue>& params) {
  ReconstructConfig ro;
  ro.method = std::get<std::string>(params.at("method"));
  ro.voxel_size = std::get<double>(params.at("voxel_m"));
  // Any other setting of the reconstruction, by its dotted path (checked when the sweep was
  // loaded): reconstruct.bracket.min_bracket, reconstruct.deconv.mode, ...
  for (const auto& [name, value] : params) {
    if (name.rfind("reconstruct.", 0) != 0) continue;
    params::set_dotted(ro, name.substr(12), YAML::Node(to_string(value)), "sweep", "reconstruct");
  }
  // The object and a 0.3 m margin, but nothing more than 3 cm below its base: the reference
  // objects stand on the seabed, which the simulated scene leaves out. Without this seabed
  // prior the lowest frames of a pass (which start below the base to bracket it) see the
  // underside of base plates, and both methods put their unbracketed elevation arcs below the
  // seabed (docs/carving.md). The 3 cm keep surfaces lying on the seabed, which reconstruct on
  // both sides of it (cutting at the base took the pillar's deconvolution coverage from 32 to
  // 21 %). It also keeps the map (and memory) to the inspected volume.
  const Eigen::AlignedBox3d box = setup.scene.objects[0].mesh_world.bounding_box().cast<double>();
  Eigen::AlignedBox3d roi = box;
  roi.extend(box.min() - Eigen::Vector3d(0.3, 0.3, 0.03));
  roi.extend(box.max() + Eigen::Vector3d::Constant(0.3));
  ro.region = roi;
  return ro;
}

MemoryEstimate estimate_plan_point_memory(const SimulationSetup& setup,
                                          const std::map<std::string, SweepValue>& params,
                                          double limit_bytes) {
  const ReconstructConfig ro = plan_reconstruct_config(setup, params);
  MemoryEstimate e;
  // As check_reconstruct_memory: the passes mode of the deconvolution allocates per column.
  if (ro.method != "carve" && ro.effective_deconv().mode == DeconvConfig::Mode::Passes) return e;
  std::vector<Eigen::Isometry3d> poses;
  poses.reserve(setup.T_world_vehicle.size());
  for (const auto& T : setup.T_world_vehicle.poses) poses.push_back(T * setup.spec.T_vehicle_sonar);
  e = estimate_carve_memory(setup.spec, poses, ro.effective_carve(), limit_bytes);
  for (auto& part : e.parts) {
    if (part.option == "--voxel-size") part.option = "voxel_m";
  }
  return e;
}

void run_sweep_point(const fs::path& out_dir, std::size_t index) {
  const Sweep sweep = load_sweep((out_dir / "sweep.yaml").string());
  const auto params = sweep.point(index);
  const std::string id = point_id(index);
  const fs::path dir = out_dir / "points" / id;
  fs::create_directories(dir);
  // A re-run replaces what an earlier run of this point left: until this one finishes, the point
  // has no status (the planner records a failure if the worker dies) and no dataset/.
  const fs::path ds_dir = dir / kPartialDatasetName, ds_final = dir / "dataset";
  for (const fs::path& old : {dir / "status.json", ds_final, ds_dir}) fs::remove_all(old);
  nlohmann::json status;
  status["id"] = id;
  status["index"] = index;
  status["params_key"] = plan_params_key(params);
  status["params"] = plan_params_json(params);
  const auto t0 = std::chrono::steady_clock::now();
  try {
    const SimulationSetup setup = plan_setup(
        sweep, params, sweep.source.empty() ? out_dir : fs::path(sweep.source).parent_path());
    const SimulationStats sim = simulate_dataset(setup, ds_dir, false);
    const Dataset ds = read_dataset(ds_dir);
    ReconstructConfig ro = plan_reconstruct_config(setup, params);
    ro.num_threads = plan_threads_per_point();
    const ReconstructResult rec = reconstruct_dataset(ds, ro);
    if (rec.cloud.empty()) {
      throw Error("the " + ro.method + " reconstruction has no point" +
                  (rec.notes.empty() ? std::string() : " (" + rec.notes + ")") +
                  ": this configuration sees nothing usable of the object");
    }
    write_ply((dir / "cloud.ply").string(), rec.cloud);
    const auto results = evaluate_objects(rec.cloud, setup.scene.objects, EvalConfig{});
    nlohmann::json metrics = nlohmann::json::array();
    for (const auto& r : results) {
      nlohmann::json item = nlohmann::json::parse(to_json(r.result));
      item["object"] = r.name;
      metrics.push_back(item);
    }
    write_text_file((dir / "metrics.json").string(), metrics.dump(2) + "\n");
    const nlohmann::json& all = metrics.back();
    status["metrics"] = {{"median_error_m", all["median_error_m"]},
                         {"mean_error_m", all["mean_error_m"]},
                         {"coverage", all["coverage"]},
                         {"outliers", all["outliers"]},
                         {"median_to_coverage", all["median_to_coverage_cm_per_pct"]},
                         {"num_points", all["num_points"]}};
    status["data_bytes"] = directory_bytes(ds_dir);
    status["frames"] = sim.frames;
    status["simulate_s"] = sim.seconds;
    status["reconstruct_s"] = rec.seconds;
    status["cloud"] = "points/" + id + "/cloud.ply";
    status["objects"] = {setup.scene.objects[0].name};
    status["status"] = "ok";
    status["message"] = rec.notes;
    // Truth meshes are shared by every point that uses the object.
    const fs::path truth = out_dir / "truth" / (setup.scene.objects[0].name + ".ply");
    if (!fs::exists(truth)) {
      fs::create_directories(truth.parent_path());
      save_mesh(truth.string(), setup.scene.objects[0].mesh_world);
    }
    if (sweep.keep_datasets) {
      fs::rename(ds_dir, ds_final);
    } else {
      fs::remove_all(ds_dir);
    }
  } catch (const std::exception& e) {
    status["status"] = "failed";
    status["message"] = e.what();
    std::error_code ec;
    fs::remove_all(ds_dir, ec);
  }
  status["runtime_s"] =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  write_text_file((dir / "status.json").string(), status.dump(2) + "\n");
}

}  // namespace sonar3d
