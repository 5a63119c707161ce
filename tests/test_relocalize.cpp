// Relocalisation against a world model (issue 26 item 4, world/relocalize.hpp): a small simulated
// site is surveyed, carved and turned into a world model (seabed + one placed box); a second,
// single line over it, logged with a known offset and rotation, is relocalised back onto the
// truth, and a line beside the model is "not found".
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <vector>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/reference_objects.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/world/change.hpp"
#include "sonar3d/world/relocalize.hpp"
#include "sonar3d/world/world_model.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using sonar3d::test::CliRun;
using sonar3d::test::run_cli;

namespace {

constexpr double kDeg = M_PI / 180;

fs::path temp_dir() {
  const fs::path d =
      fs::temp_directory_path() / ("sonar3d_test_relocalize_" + std::to_string(getpid()));
  fs::create_directories(d);
  return d;
}

// A 40 × 40 m seabed with relief and rocks, a box on it; a downward-looking 1° × 80° sonar 3 m
// above. TRAJECTORY is replaced per survey.
const std::string kScene = std::string(R"(seed: 4
)") + sonar3d::test::kDownwardSonarYaml +
                           R"(objects:
  - {name: seabed, primitive: {type: terrain, size: [40, 40], cell: 0.05, relief: 0.3, wavelength: 4, rocks: 60, seed: 4}, reflectivity: 0.3}
  - {name: box, primitive: {type: box, size: [1.0, 0.6, 0.4]}, pose: {translation: [1.5, -1.0, 0.1], rpy_deg: [0, 0, 30]}, reflectivity: 0.8}
trajectory: TRAJECTORY
)";

void simulate(const fs::path& dir, const std::string& name, const std::string& trajectory,
              const std::string& box_translation = "") {
  std::string scene = kScene;
  if (!box_translation.empty()) {  // the box moved (a later survey of a changed site)
    const std::string at = "[1.5, -1.0, 0.1]";
    scene.replace(scene.find(at), at.size(), box_translation);
  }
  scene.replace(scene.find("TRAJECTORY"), 10, trajectory);
  { std::ofstream(dir / (name + ".yaml")) << scene; }
  const CliRun r = run_cli(dir, "simulate " + (dir / (name + ".yaml")).string() + " -o " +
                                    (dir / name).string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
}

// The world model of survey A (its navigation exact): carved, the box placed where it is. With
// `cloud_file`, A's cloud is written there too and the world records it as its map (as `sonar3d
// world MAP` does).
void build_world(const fs::path& dataset, const fs::path& world_dir,
                 const fs::path& cloud_file = {}) {
  const sonar3d::Dataset ds = sonar3d::read_dataset(dataset);
  sonar3d::CarveConfig cc;
  cc.voxel_size = 0.03;
  sonar3d::Carver carver(ds.spec, cc, ds.noise);
  for (std::size_t i = 0; i < ds.size(); ++i)
    carver.integrate(ds.load_frame(i), ds.T_world_sonar(i));
  const sonar3d::PointCloud cloud = carver.finalize();
  sonar3d::WorldObject box;
  box.id = "box_0";
  box.model = "box";
  box.T_world_model.translation() = Eigen::Vector3d(1.5, -1.0, 0.1);
  box.T_world_model.linear() = Eigen::AngleAxisd(30 * kDeg, Eigen::Vector3d::UnitZ()).matrix();
  box.mesh_model = std::make_shared<sonar3d::TriangleMesh>(sonar3d::make_box(1.0, 0.6, 0.4));
  const sonar3d::WorldModel world =
      sonar3d::build_world_model(cloud, {box}, sonar3d::WorldModelConfig{});
  sonar3d::WorldWriteInfo info;
  if (!cloud_file.empty()) {
    sonar3d::write_ply(cloud_file.string(), cloud);
    info.map = cloud_file.string();
  }
  sonar3d::write_world_model(world_dir, world, info);
}

// The dataset carved as its navigation says (a map made as logged).
void carve_dataset(const fs::path& dataset, const fs::path& cloud_file) {
  const sonar3d::Dataset ds = sonar3d::read_dataset(dataset);
  sonar3d::CarveConfig cc;
  cc.voxel_size = 0.03;
  sonar3d::Carver carver(ds.spec, cc, ds.noise);
  for (std::size_t i = 0; i < ds.size(); ++i)
    carver.integrate(ds.load_frame(i), ds.T_world_sonar(i));
  sonar3d::write_ply(cloud_file.string(), carver.finalize());
}

// Logged = E · true for every pose of a dataset's navigation.
void offset_navigation(const fs::path& dataset, const Eigen::Isometry3d& E) {
  sonar3d::Trajectory nav = sonar3d::read_tum((dataset / "navigation.tum").string());
  for (auto& T : nav.poses) T = E * T;
  sonar3d::write_tum((dataset / "navigation.tum").string(), nav);
}

std::string placements_json(double x, double y) {
  const double c = std::cos(30 * kDeg), s = std::sin(30 * kDeg);
  return "{\"format\": \"sonar3d-placements\", \"version\": 1, \"placements\": [{\"model\": "
         "\"box\", \"T_world_model\": [[" +
         std::to_string(c) + ", " + std::to_string(-s) + ", 0, " + std::to_string(x) + "], [" +
         std::to_string(s) + ", " + std::to_string(c) + ", 0, " + std::to_string(y) +
         "], [0, 0, 1, 0.1], [0, 0, 0, 1]]}]}";
}

// Area of the change regions of a changes.json whose centroid lies farther than `radius` from
// every point of `near` (the seabed's changes, away from the structures), m².
double area_away_from(const nlohmann::json& changes, const std::vector<Eigen::Vector2d>& near,
                      double radius) {
  double area = 0;
  for (const auto& g : changes["regions"]) {
    const Eigen::Vector2d c(g["centroid"][0].get<double>(), g["centroid"][1].get<double>());
    bool close = false;
    for (const auto& p : near) close = close || (c - p).norm() < radius;
    if (!close) area += g["area_m2"].get<double>();
  }
  return area;
}

nlohmann::json read_json(const fs::path& path) {
  std::ifstream f(path);
  return nlohmann::json::parse(f);
}

}  // namespace

TEST(Relocalize, RecoversAKnownOffsetAndRotationAndSaysNotFoundOutsideTheModel) {
  const fs::path dir = temp_dir();
  simulate(dir, "a",
           "{type: lawnmower, x: [-5, 5], y: [-3, 3], z: 3.0, line_spacing: 1.5, spacing: 0.04, "
           "period: 0.1}");
  build_world(dir / "a", dir / "world");
  ASSERT_TRUE(fs::exists(dir / "world/graph.json"));
  const sonar3d::WorldModelCloud w = sonar3d::read_world_model_cloud(dir / "world", 0.03);
  EXPECT_EQ(w.structures, 1u);
  EXPECT_GT(w.structure_points, 1000u);

  // Survey B: one line across the model, logged turned by 3° about (2, 1) and shifted by
  // (0.4, -0.3, 0.05) m: logged = E · true.
  simulate(dir, "b",
           "{type: straight, start: [-4.5, 0.4, 3.0], end: [4.5, 0.4, 3.0], spacing: 0.04}");
  const sonar3d::Trajectory truth = sonar3d::read_tum((dir / "b/navigation.tum").string());
  const Eigen::Vector3d pivot(2, 1, 0), shift(0.4, -0.3, 0.05);
  Eigen::Isometry3d E = Eigen::Isometry3d::Identity();
  E.linear() = Eigen::AngleAxisd(3 * kDeg, Eigen::Vector3d::UnitZ()).matrix();
  E.translation() = pivot + shift - E.linear() * pivot;
  sonar3d::Trajectory logged = truth;
  for (auto& T : logged.poses) T = E * T;
  sonar3d::write_tum((dir / "b/navigation.tum").string(), logged);

  CliRun r = run_cli(dir, "relocalize " + (dir / "b").string() + " --world " +
                              (dir / "world").string() + " -o " + (dir / "rb").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("relocalize: found"), std::string::npos) << r.out;
  std::cout << r.out;
  const sonar3d::Trajectory corrected = sonar3d::read_tum((dir / "rb/navigation.tum").string());
  ASSERT_EQ(corrected.size(), truth.size());
  double worst = 0, worst_yaw = 0;
  std::vector<double> horizontal;
  for (std::size_t k = 0; k < truth.size(); ++k) {
    const Eigen::Vector3d e = corrected.poses[k].translation() - truth.poses[k].translation();
    worst = std::max(worst, e.norm());
    horizontal.push_back(e.head<2>().norm());
    const Eigen::Matrix3d dR = corrected.poses[k].linear() * truth.poses[k].linear().transpose();
    worst_yaw = std::max(worst_yaw, Eigen::AngleAxisd(dR).angle());
  }
  std::nth_element(horizontal.begin(), horizontal.begin() + horizontal.size() / 2,
                   horizontal.end());
  const double median = horizontal[horizontal.size() / 2];
  // 5 cm voxels, 10 cm registration cells: every pose within 5 cm, half within 2 cm, the heading
  // within 0.3° (the logged one was 3° and 0.5 m off).
  EXPECT_LT(worst, 0.05) << r.out;
  EXPECT_LT(median, 0.02) << r.out;
  EXPECT_LT(worst_yaw, 0.3 * kDeg) << r.out;
  std::cout << "position error: worst " << worst << " m, horizontal median " << median
            << " m; heading " << worst_yaw / kDeg << " deg\n";
  std::ifstream f(dir / "rb/relocalization.json");
  const nlohmann::json j = nlohmann::json::parse(f);
  EXPECT_EQ(j["format"], "sonar3d-relocalization");
  EXPECT_TRUE(j["found"].get<bool>());
  ASSERT_EQ(j["swaths"].size(), 1u);
  const auto& s = j["swaths"][0];
  std::cout << "drift " << s["drift"].dump() << ", sigma " << s["sigma_hessian_m"] << " (Hessian) "
            << s["sigma_pieces_m"] << " (pieces)\n";
  EXPECT_NEAR(s["yaw_deg"].get<double>(), -3.0, 0.3);
  EXPECT_GT(s["overlap_fraction"].get<double>(), 0.8);
  // σ is stated and plausible: finite, not above a few cm.
  ASSERT_TRUE(s["sigma_horizontal_m"].is_number());
  EXPECT_GT(s["sigma_horizontal_m"].get<double>(), 0.0);
  EXPECT_LT(s["sigma_horizontal_m"].get<double>(), 0.05);

  // The coarse-to-fine yaw search (yaw_refine_best: every yaw scored at whole-cell shifts, the
  // best few searched sub-cell) ends where the exhaustive one (every yaw searched sub-cell) ends,
  // for relocalize's search (±5° every 0.25°, ±1 m) and its refinement from that solution
  // (±0.5° every 0.05°, ±0.2 m): the same yaw within one step, the same shift within one cell.
  {
    const sonar3d::Dataset ds = sonar3d::read_dataset(dir / "b");
    sonar3d::CarveConfig cc;
    cc.voxel_size = 0.05;
    sonar3d::Carver carver(ds.spec, cc, ds.noise);
    for (std::size_t i = 0; i < ds.size(); ++i) {
      carver.integrate(ds.load_frame(i), ds.T_world_sonar(i));
    }
    const sonar3d::PointCloud swath = carver.finalize();
    sonar3d::ChangeRegistrationConfig coarse = sonar3d::RelocalizeConfig{}.registration;
    ASSERT_GT(coarse.yaw_refine_best, 0);  // relocalize's default is the coarse-to-fine search
    sonar3d::ChangeRegistrationConfig fine = coarse;
    fine.search_m = 2 * coarse.cell_m;
    fine.yaw_cell_m = coarse.cell_m;
    fine.yaw_search_deg = 2 * coarse.yaw_step_deg;
    fine.yaw_step_deg = 0.2 * coarse.yaw_step_deg;
    sonar3d::PointCloud moved;
    double yaw_total = 0;
    for (sonar3d::ChangeRegistrationConfig* c : {&coarse, &fine}) {
      const sonar3d::PointCloud& b = c == &coarse ? swath : moved;
      sonar3d::ChangeRegistrationConfig exhaustive = *c;
      exhaustive.yaw_refine_best = 0;
      const sonar3d::ChangeRegistration fast = sonar3d::register_surveys(w.cloud, b, *c);
      const sonar3d::ChangeRegistration full = sonar3d::register_surveys(w.cloud, b, exhaustive);
      EXPECT_LE(std::abs(fast.yaw_deg - full.yaw_deg), c->yaw_step_deg + 1e-9)
          << fast.yaw_deg << " vs " << full.yaw_deg;
      EXPECT_LE((fast.T_a_b.translation() - full.T_a_b.translation()).head<2>().norm(), c->cell_m)
          << fast.T_a_b.translation().transpose() << " vs " << full.T_a_b.translation().transpose();
      std::cout << "yaw search ±" << c->yaw_search_deg << " deg: coarse-to-fine " << fast.yaw_deg
                << " deg, " << fast.seconds << " s; exhaustive " << full.yaw_deg << " deg, "
                << full.seconds << " s\n";
      yaw_total += full.yaw_deg;
      if (c == &coarse) {
        moved.points.reserve(swath.size());
        for (const auto& p : swath.points) {
          moved.points.push_back((full.T_a_b * p.cast<double>()).cast<float>());
        }
      }
    }
    // The logged line was turned by 3°: search and refinement together find it within 0.3°.
    EXPECT_NEAR(yaw_total, -3.0, 0.3);
  }

  // Survey A itself, five lines and their turns, against its own model: every swath found, the
  // navigation (exact) left within 3 cm, the turns' poses too (blended between swaths).
  r = run_cli(dir, "relocalize " + (dir / "a").string() + " --world " + (dir / "world").string() +
                       " -o " + (dir / "ra").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("(5/5 swaths)"), std::string::npos) << r.out;
  {
    const sonar3d::Trajectory nav_a = sonar3d::read_tum((dir / "a/navigation.tum").string());
    const sonar3d::Trajectory back = sonar3d::read_tum((dir / "ra/navigation.tum").string());
    ASSERT_EQ(back.size(), nav_a.size());
    std::vector<double> e;
    for (std::size_t k = 0; k < nav_a.size(); ++k) {
      e.push_back((back.poses[k].translation() - nav_a.poses[k].translation()).head<2>().norm());
    }
    const double worst_a = *std::max_element(e.begin(), e.end());
    std::nth_element(e.begin(), e.begin() + e.size() / 2, e.end());
    // Each 10 m swath carved alone fits the five lines' model about 2.5 cm along its track and
    // turned by up to 0.25° (docs/mapping.md "Relocalisation": the model's own error, as on the
    // field): centimetres.
    EXPECT_LT(e[e.size() / 2], 0.03) << r.out;
    EXPECT_LT(worst_a, 0.07) << r.out;
    std::cout << r.out << "survey A against its own model: horizontal median " << e[e.size() / 2]
              << " m, worst " << worst_a << " m\n";
  }

  // A line 12 m north, over seabed of the same kind that the model does not hold: not found
  // (exit status 3, the JSON saying why, no navigation written).
  simulate(dir, "c",
           "{type: straight, start: [-4.5, 12.0, 3.0], end: [4.5, 12.0, 3.0], spacing: 0.04}");
  r = run_cli(dir, "relocalize " + (dir / "c").string() + " --world " + (dir / "world").string() +
                       " -o " + (dir / "rc").string() + " -q");
  EXPECT_EQ(r.code, 3) << r.out;
  EXPECT_NE(r.out.find("NOT FOUND"), std::string::npos) << r.out;
  std::cout << r.out;
  EXPECT_FALSE(fs::exists(dir / "rc/navigation.tum"));
  std::ifstream fc(dir / "rc/relocalization.json");
  const nlohmann::json jc = nlohmann::json::parse(fc);
  EXPECT_FALSE(jc["found"].get<bool>());
  EXPECT_FALSE(jc["swaths"][0]["reason"].get<std::string>().empty());

  // A line only 4 m north of the model's last line: its search window may graze the model, and
  // its overlap fraction or distinctiveness must still say "not found".
  simulate(dir, "d",
           "{type: straight, start: [-4.5, 7.5, 3.0], end: [4.5, 7.5, 3.0], spacing: 0.04}");
  r = run_cli(dir, "relocalize " + (dir / "d").string() + " --world " + (dir / "world").string() +
                       " -o " + (dir / "rd").string() + " -q");
  EXPECT_EQ(r.code, 3) << r.out;
  std::cout << r.out;

  // Bad inputs: one clear line each.
  r = run_cli(dir, "relocalize " + (dir / "b").string() + " --world " + (dir / "nowhere").string() +
                       " -o " + (dir / "x1").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("does not exist"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  fs::create_directories(dir / "noseabed");
  {
    std::ofstream(dir / "noseabed/graph.json")
        << R"({"format": "sonar3d-world", "version": 1, "seabed": []})";
  }
  r = run_cli(dir, "relocalize " + (dir / "b").string() + " --world " +
                       (dir / "noseabed").string() + " -o " + (dir / "x2").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("has no seabed"), std::string::npos) << r.out;
  // An existing output that relocalize did not write is refused; its own is replaced with
  // --overwrite.
  r = run_cli(dir, "relocalize " + (dir / "b").string() + " --world " + (dir / "world").string() +
                       " -o " + (dir / "a").string() + " -q");
  EXPECT_EQ(r.code, 1) << r.out;
  r = run_cli(dir, "relocalize " + (dir / "b").string() + " --world " + (dir / "world").string() +
                       " -o " + (dir / "rb").string() + " -q --overwrite");
  EXPECT_EQ(r.code, 0) << r.out;

  // A run from the configuration a run printed gives the same relocalisation: the same navigation,
  // byte for byte, and the same relocalization.json but for its timings.
  const std::string flags = " --piece 4 --search 0.8 --min-overlap 0.4 --threads 1";
  r = run_cli(dir, "relocalize --print-config" + flags);
  ASSERT_EQ(r.code, 0) << r.out;
  { std::ofstream(dir / "reloc.yaml") << r.out; }
  const std::string in =
      "relocalize " + (dir / "b").string() + " --world " + (dir / "world").string() + " -q";
  r = run_cli(dir, in + " -o " + (dir / "cfg_flags").string() + flags);
  ASSERT_EQ(r.code, 0) << r.out;
  r = run_cli(dir, in + " -o " + (dir / "cfg_file").string() + " --config " +
                       (dir / "reloc.yaml").string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(sonar3d::test::read_all(dir / "cfg_flags/navigation.tum"),
            sonar3d::test::read_all(dir / "cfg_file/navigation.tum"));
  const auto without_timings = [](const fs::path& path) {
    std::ifstream in(path);
    nlohmann::json j = nlohmann::json::parse(in);
    j.erase("seconds");
    for (auto& s : j["swaths"]) s.erase("seconds");
    return j;
  };
  const nlohmann::json jf = without_timings(dir / "cfg_flags/relocalization.json");
  EXPECT_EQ(jf, without_timings(dir / "cfg_file/relocalization.json"));
  EXPECT_EQ(jf["swaths"].size(), 1u);
  EXPECT_EQ(jf["criterion"]["search_m"].get<double>(), 0.8);  // the file's, not the default
  EXPECT_EQ(jf["criterion"]["min_overlap_fraction"].get<double>(), 0.4);
  fs::remove_all(dir);
}

// Change detection through relocalisation (issue 26 item 4: "the second survey of a change
// detection can go through it"): survey B of a site whose box moved 1 m, logged 4° and 1.8 m
// off (beyond diff's own ±0.6 m, ±2° search; relocalised with --search 1.6). Compared as logged,
// diff's registration cannot place B and the seabed shows large changes; relocalised against A's
// world model and carved with the relocalised navigation, B is in A's frame: the seabed is
// unchanged and the moved box is reported (its regions of change, and the object moved).
TEST(Relocalize, ChangeDetectionThroughRelocalisation) {
  const fs::path dir = temp_dir() / "diff";
  fs::create_directories(dir);
  simulate(dir, "a",
           "{type: lawnmower, x: [-5, 5], y: [-3, 3], z: 3.0, line_spacing: 1.5, spacing: 0.04, "
           "period: 0.1}");
  build_world(dir / "a", dir / "world", dir / "a.ply");
  const Eigen::Vector2d box_a(1.5, -1.0), box_b(1.5, 0.0);
  simulate(dir, "b",
           "{type: lawnmower, x: [-5, 5], y: [-2.25, 2.25], z: 3.0, line_spacing: 1.5, "
           "spacing: 0.04, period: 0.1}",
           "[1.5, 0.0, 0.1]");
  // Logged turned by 4° about the site's centre and shifted by (1.4, -1.1, 0.05) m.
  Eigen::Isometry3d E = Eigen::Isometry3d::Identity();
  E.linear() = Eigen::AngleAxisd(4 * kDeg, Eigen::Vector3d::UnitZ()).matrix();
  E.translation() = Eigen::Vector3d(1.4, -1.1, 0.05);
  offset_navigation(dir / "b", E);
  { std::ofstream(dir / "pa.json") << placements_json(box_a.x(), box_a.y()); }
  // B's recognition in its relocalised map (A's frame) places the box where it now stands.
  { std::ofstream(dir / "pb.json") << placements_json(box_b.x(), box_b.y()); }
  const std::string placements = " --placements-a " + (dir / "pa.json").string() +
                                 " --placements-b " + (dir / "pb.json").string();

  // As logged: B's map carved with its own navigation.
  carve_dataset(dir / "b", dir / "b_logged.ply");
  CliRun r =
      run_cli(dir, "diff " + (dir / "a.ply").string() + " " + (dir / "b_logged.ply").string() +
                       " -o " + (dir / "d_logged").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  const nlohmann::json logged = read_json(dir / "d_logged/changes.json");
  // The box's regions: lowered where it stood (A), raised where it stands (B).
  const auto box_regions = [&](const nlohmann::json& changes) {
    bool lowered_at_a = false, raised_at_b = false;
    for (const auto& g : changes["regions"]) {
      const Eigen::Vector2d c(g["centroid"][0].get<double>(), g["centroid"][1].get<double>());
      const bool raised = g["kind"] == "raised";
      lowered_at_a = lowered_at_a || (!raised && (c - box_a).norm() < 0.4);
      raised_at_b = raised_at_b || (raised && (c - box_b).norm() < 0.4);
    }
    return std::make_pair(lowered_at_a, raised_at_b);
  };
  std::cout << r.out << "as logged: " << logged["regions"].size() << " regions, sigma of B - A "
            << logged["thresholds"]["sigma_m"] << " m, rms " << logged["registration"]["rms_m"]
            << " m\n";
  // diff's own registration (±0.6 m, ±2°) cannot place B: the seabed differs everywhere, which
  // raises the noise it derives its threshold from and hides the box's move (checked against
  // the relocalised run below).
  const auto [lowered_logged, raised_logged] = box_regions(logged);
  EXPECT_FALSE(lowered_logged && raised_logged) << logged["regions"].dump();

  // Relocalised against A's world model, carved with the relocalised navigation.
  r = run_cli(dir, "relocalize " + (dir / "b").string() + " --world " + (dir / "world").string() +
                       " -o " + (dir / "rb").string() + " --search 1.6 --map-resolution 0.03 -q");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("merged.ply (survey B of sonar3d diff)"), std::string::npos) << r.out;
  ASSERT_TRUE(fs::exists(dir / "rb/merged.ply"));
  const nlohmann::json jr = read_json(dir / "rb/relocalization.json");
  EXPECT_EQ(jr["map"], "merged.ply");
  EXPECT_EQ(jr["map_voxel_m"].get<double>(), 0.03);
  EXPECT_GT(jr["map_points"].get<std::size_t>(), 10000u);
  r = run_cli(dir, "diff " + (dir / "a.ply").string() + " " + (dir / "rb").string() + " -o " +
                       (dir / "d_reloc").string() + placements);
  ASSERT_EQ(r.code, 0) << r.out;
  std::cout << r.out;
  EXPECT_NE(r.out.find("not registered again"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("B onto A (relocalised)"), std::string::npos) << r.out;
  const nlohmann::json reloc = read_json(dir / "d_reloc/changes.json");
  EXPECT_EQ(reloc["registration"]["method"].get<std::string>().rfind("relocalized against", 0), 0u);
  const double seabed_reloc = area_away_from(reloc, {box_a, box_b}, 1.5);
  std::cout << "relocalised: " << reloc["regions"].size() << " regions, " << seabed_reloc
            << " m2 of change away from the box, sigma of B - A " << reloc["thresholds"]["sigma_m"]
            << " m, rms " << reloc["registration"]["rms_m"] << " m\n";
  // The seabed unchanged: no change away from the box, its differences a third of the logged
  // ones or less.
  EXPECT_EQ(seabed_reloc, 0.0) << r.out;
  EXPECT_LT(3 * reloc["thresholds"]["sigma_m"].get<double>(),
            logged["thresholds"]["sigma_m"].get<double>());
  EXPECT_LT(3 * reloc["registration"]["rms_m"].get<double>(),
            logged["registration"]["rms_m"].get<double>());
  EXPECT_LT(reloc["registration"]["rms_m"].get<double>(), 0.03);
  // The box: lowered where it stood, raised where it stands, and the object moved by 1 m.
  const auto [lowered_reloc, raised_reloc] = box_regions(reloc);
  EXPECT_TRUE(lowered_reloc) << reloc["regions"].dump();
  EXPECT_TRUE(raised_reloc) << reloc["regions"].dump();
  ASSERT_EQ(reloc["objects"].size(), 1u) << reloc["objects"].dump();
  EXPECT_EQ(reloc["objects"][0]["status"], "moved") << reloc["objects"].dump();
  EXPECT_NEAR(reloc["objects"][0]["shift_m"].get<double>(), (box_a - box_b).norm(), 0.01);

  // Relocalised against a world model of another map than A: B is registered as usual, and the
  // warning says why (here A's cloud under another name).
  fs::copy_file(dir / "a.ply", dir / "a_copy.ply");
  r = run_cli(dir, "diff " + (dir / "a_copy.ply").string() + " " + (dir / "rb").string() + " -o " +
                       (dir / "d_other").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("registered onto A as usual"), std::string::npos) << r.out;
  EXPECT_NE(read_json(dir / "d_other/changes.json")["registration"]["method"].get<std::string>(),
            reloc["registration"]["method"].get<std::string>());

  // A relocalisation without its map: one error line naming the directory and the flag.
  fs::create_directories(dir / "rb_nomap");
  fs::copy_file(dir / "rb/relocalization.json", dir / "rb_nomap/relocalization.json");
  r = run_cli(dir, "diff " + (dir / "a.ply").string() + " " + (dir / "rb_nomap").string() + " -o " +
                       (dir / "d_nomap").string());
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("rb_nomap"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("--map-resolution"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_FALSE(fs::exists(dir / "d_nomap"));
  fs::remove_all(dir);
}
