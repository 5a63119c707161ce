// `sonar3d report`: the page written for a fixture plan directory (a 2 objects × 3 apertures ×
// 3 spacings × 2 methods sweep with one failed point, clouds sampled on the CAD surfaces with
// aperture-dependent noise) is self-contained, embeds the data and the per-point errors
// exactly, subsamples and simplifies as configured, fails clearly on bad input, and renders in
// headless Chromium (web/test_report.mjs).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <string>
#include <tuple>
#include <utility>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/report/report.hpp"
#include "sonar3d/sim/reference_objects.hpp"
#include "sonar3d/video/texture_mesh.hpp"
#include "sonar3d/world/change.hpp"

namespace fs = std::filesystem;
// ordered_json, as the planner writes results.json: the axes keep the sweep's order.
using json = nlohmann::ordered_json;

namespace sonar3d {
namespace {

const fs::path kWebDir = fs::path(SONAR3D_SOURCE_DIR) / "web";

std::vector<unsigned char> unbase64(const std::string& s) {
  auto val = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  };
  std::vector<unsigned char> out;
  unsigned buf = 0;
  int bits = 0;
  for (char c : s) {
    const int v = val(c);
    if (v < 0) continue;  // '=' padding
    buf = (buf << 6) | static_cast<unsigned>(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<unsigned char>((buf >> bits) & 0xff));
    }
  }
  return out;
}

std::vector<float> floats(const std::string& b64) {
  const auto bytes = unbase64(b64);
  std::vector<float> f(bytes.size() / sizeof(float));
  std::memcpy(f.data(), bytes.data(), f.size() * sizeof(float));
  return f;
}

// The JSON embedded in the page's <script type="application/json" id="sonar3d-data">.
json embedded_data(const std::string& html) {
  const std::string open = "id=\"sonar3d-data\">";
  const std::size_t a = html.find(open);
  EXPECT_NE(a, std::string::npos);
  const std::size_t b = html.find("</script>", a);
  return json::parse(html.substr(a + open.size(), b - a - open.size()));
}

// A plan directory as `sonar3d plan` writes it (docs/report.md, the planner's contract).
struct FixtureOptions {
  int cloud_points = 1500;
  int sphere_segments = 48;
};

// Writes an ok point's cloud under dir/points/<id>/ and fills its results.json entry (status,
// metrics as the planner writes them, cloud path); returns the evaluation.
EvalResult write_ok_point(const fs::path& dir, const std::string& id, const PointCloud& cloud,
                          const TriangleMesh& truth, const EvalConfig& ecfg, json& p) {
  const std::string rel = "points/" + id + "/cloud.ply";
  fs::create_directories(dir / "points" / id);
  write_ply((dir / rel).string(), cloud);
  const EvalResult r = evaluate(cloud, truth, ecfg);
  p["status"] = "ok";
  p["message"] = "";
  p["metrics"] = {{"median_error_m", r.median_error},
                  {"mean_error_m", r.mean_error},
                  {"coverage", r.coverage},
                  {"outliers", r.outliers},
                  {"median_to_coverage", r.median_to_coverage},
                  {"num_points", r.num_points}};
  p["cloud"] = rel;
  return r;
}

fs::path make_plan_dir(const fs::path& dir, const FixtureOptions& opt = {}) {
  fs::create_directories(dir / "truth");
  std::map<std::string, TriangleMesh> truth;
  truth["sphere"] = make_sphere(0.5, opt.sphere_segments);
  {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(0, 0, 0.5);  // resting on z = 0 like the reference sphere
    truth["sphere"].transform(T);
  }
  truth["tank"] = make_reference_object("tank");
  {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(0, 4, 0);  // 4 m along y, as in the default scene
    truth["tank"].transform(T);
  }
  for (const auto& [name, mesh] : truth)
    save_mesh((dir / "truth" / (name + ".ply")).string(), mesh);

  const std::vector<std::string> objects = {"sphere", "tank"};
  const std::vector<double> apertures = {1, 10, 20};
  const std::vector<double> spacings = {0.01, 0.02, 0.05};
  const std::vector<std::string> methods = {"carve", "deconv"};
  json results = json::object();
  results["version"] = 1;
  results["rank_by"] = "median_to_coverage";
  results["rank_order"] = "ascending";
  results["constraints"] = json::array({"spacing_m <= 0.05"});
  results["axes"] = {{"object", objects},
                     {"aperture_deg", apertures},
                     {"spacing_m", spacings},
                     {"method", methods}};
  json points = json::array();
  EvalConfig ecfg;
  ecfg.samples_per_cm2 = 0.3;
  std::mt19937_64 rng(7);
  int n = 0;
  for (const auto& obj : objects) {
    for (double ap : apertures) {
      for (double sp : spacings) {
        for (const auto& method : methods) {
          char id[16];
          std::snprintf(id, sizeof id, "p%04d", n++);
          json p;
          p["id"] = id;
          p["params"] = {
              {"object", obj}, {"aperture_deg", ap}, {"spacing_m", sp}, {"method", method}};
          p["objects"] = json::array({obj});
          p["runtime_s"] = 0.5 + ap * 0.1 + (method == "deconv" ? 1.0 : 0.0);
          p["peak_rss_mb"] = 100 + 10 * ap;
          p["data_bytes"] = static_cast<long long>(2e6 / sp);
          p["rank"] = nullptr;
          if (obj == "tank" && ap == 20 && sp == 0.05 && method == "deconv") {
            p["status"] = "failed";
            p["message"] = "deconvolve: NNLS did not converge in 200 iterations (frame 17)";
            p["metrics"] = nullptr;
            p["cloud"] = nullptr;
            points.push_back(p);
            continue;
          }
          // Noise grows with the aperture and the spacing; deconvolution is tighter, like the
          // thesis' curves; a few outliers float around the object.
          const double sigma = (0.002 + 0.0009 * ap + 0.15 * sp) * (method == "deconv" ? 0.6 : 1.0);
          const TriangleMesh& mesh = truth[obj];
          PointCloud cloud;
          const auto surf = sample_surface(mesh, opt.cloud_points, rng());
          std::normal_distribution<float> noise(0.f, static_cast<float>(sigma));
          std::uniform_real_distribution<float> u(-0.3f, 0.3f);
          for (std::size_t k = 0; k < surf.size(); ++k) {
            Eigen::Vector3f q = surf[k] + Eigen::Vector3f(noise(rng), noise(rng), noise(rng));
            if (k % 50 == 0) q += Eigen::Vector3f(u(rng), u(rng), u(rng));
            cloud.points.push_back(q);
            cloud.intensity.push_back(1.f);
          }
          const EvalResult r = write_ok_point(dir, id, cloud, mesh, ecfg, p);
          json m = json::parse(to_json(r));
          json all = m;
          all["object"] = "all";
          m["object"] = obj;
          write_text_file((dir / "points" / id / "metrics.json").string(),
                          json::array({m, all}).dump(2));
          points.push_back(p);
        }
      }
    }
  }
  // Rank the ok points by the ratio, ascending.
  std::vector<std::size_t> ok;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (points[i]["status"] == "ok") ok.push_back(i);
  }
  std::sort(ok.begin(), ok.end(), [&](std::size_t a, std::size_t b) {
    return points[a]["metrics"]["median_to_coverage"].get<double>() <
           points[b]["metrics"]["median_to_coverage"].get<double>();
  });
  for (std::size_t r = 0; r < ok.size(); ++r) points[ok[r]]["rank"] = r + 1;
  results["points"] = points;
  write_text_file((dir / "results.json").string(), results.dump(2));
  write_text_file((dir / "sweep.yaml").string(),
                  "objects: [sphere, tank]\nsensor:\n  aperture_deg: [1, 10, 20]\n"
                  "trajectory:\n  spacing_m: [0.01, 0.02, 0.05]\nmethod: [carve, deconv]\n");
  return dir;
}

// A small plan directory over arbitrary axes, for the page's axis kinds and edge cases: one point
// per combination of `grid` (parameter values), sphere and/or tank truth as named by `object`
// (default sphere), clouds of 200 points with noise growing with `snr_db` (none = noise-free)
// and real evaluate() metrics; `failed(params)` marks points failed with a message.
fs::path make_small_plan_dir(const fs::path& dir, const json& axes, const std::vector<json>& grid,
                             const std::function<bool(const json&)>& failed) {
  fs::create_directories(dir / "truth");
  std::map<std::string, TriangleMesh> truth;
  truth["sphere"] = make_sphere(0.5, 32);
  truth["tank"] = make_reference_object("tank");
  for (const auto& [name, mesh] : truth)
    save_mesh((dir / "truth" / (name + ".ply")).string(), mesh);
  json results = {{"version", 1},
                  {"rank_by", "median_to_coverage"},
                  {"rank_order", "ascending"},
                  {"constraints", json::array()},
                  {"axes", axes}};
  json points = json::array();
  EvalConfig ecfg;
  ecfg.samples_per_cm2 = 0.1;
  std::mt19937_64 rng(11);
  for (std::size_t i = 0; i < grid.size(); ++i) {
    const json& params = grid[i];
    char id[32];
    std::snprintf(id, sizeof id, "q%03zu", i);
    const std::string obj = params.value("object", std::string("sphere"));
    json p = {{"id", id},
              {"params", params},
              {"objects", json::array({obj})},
              {"runtime_s", 1.0 + 0.1 * static_cast<double>(i)},
              {"peak_rss_mb", 100.0},
              {"data_bytes", 1000000},
              {"rank", nullptr}};
    if (failed(params)) {
      p["status"] = "failed";
      p["message"] = "simulate: no frame hit the object (standoff beyond r_max)";
      p["metrics"] = nullptr;
      p["cloud"] = nullptr;
      points.push_back(p);
      continue;
    }
    const double snr = params.contains("snr_db") && params["snr_db"].is_number()
                           ? params["snr_db"].get<double>()
                           : 40.0;
    const auto sigma = static_cast<float>(0.004 + 0.3 * std::pow(10.0, -snr / 20.0));
    std::normal_distribution<float> noise(0.f, sigma);
    PointCloud cloud;
    for (const auto& q : sample_surface(truth[obj], 200, rng())) {
      cloud.points.push_back(q + Eigen::Vector3f(noise(rng), noise(rng), noise(rng)));
      cloud.intensity.push_back(1.f);
    }
    write_ok_point(dir, id, cloud, truth[obj], ecfg, p);
    points.push_back(p);
  }
  results["points"] = points;
  write_text_file((dir / "results.json").string(), results.dump(2));
  return dir;
}

// Runs web/test_report.mjs on a page (extra: its options); fails the test with the log unless
// every check passed. Skips without Node.js/Chromium only when SONAR3D_SKIP_BROWSER_TEST is set.
void run_browser_test(const fs::path& page, const fs::path& shot, const std::string& extra) {
  const char* chromium_env = std::getenv("SONAR3D_CHROMIUM");
  const std::string chromium = chromium_env ? chromium_env : "/usr/bin/chromium";
  ASSERT_EQ(std::system("command -v node > /dev/null 2>&1"), 0)
      << "the browser test needs Node.js: run scripts/install-deps.sh "
         "(or set SONAR3D_SKIP_BROWSER_TEST=1)";
  ASSERT_TRUE(fs::exists(chromium))
      << "the browser test needs Chromium at " << chromium
      << ": run scripts/install-deps.sh (or set SONAR3D_CHROMIUM / SONAR3D_SKIP_BROWSER_TEST=1)";
  ASSERT_TRUE(fs::exists(kWebDir / "node_modules/playwright-core"))
      << "the browser test needs web/node_modules: run scripts/install-deps.sh (npm ci in web/)";
  const fs::path log = fs::path(shot).replace_extension(".txt");
  const std::string cmd = "node '" + (kWebDir / "test_report.mjs").string() + "' '" +
                          page.string() + "' --screenshot '" + shot.string() + "' --chromium '" +
                          chromium + "' " + extra + " > '" + log.string() + "' 2>&1";
  const int rc = std::system(cmd.c_str());
  const std::string out = read_text_file(log.string());
  std::printf("%s", out.c_str());
  EXPECT_EQ(rc, 0) << out;
  EXPECT_NE(out.find(" 0 failed"), std::string::npos);
  EXPECT_TRUE(fs::exists(shot));
}

// Reads the web assets of this source tree.
ReportConfig report_test_config() {
  ReportConfig cfg;
  cfg.web_dir = kWebDir;
  return cfg;
}

class ReportTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = fs::temp_directory_path() / ("sonar3d_test_report_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    make_plan_dir(root_ / "plan");
  }
  static void TearDownTestSuite() {
    if (std::getenv("SONAR3D_KEEP_TEST_OUTPUT") == nullptr) fs::remove_all(root_);
  }
  static ReportConfig config() { return report_test_config(); }
  // A copy of the fixture plan directory to damage.
  static fs::path copy_plan(const std::string& name) {
    const fs::path d = root_ / name;
    fs::remove_all(d);
    fs::copy(root_ / "plan", d, fs::copy_options::recursive);
    fs::remove(d / "report.html");
    return d;
  }
  static fs::path root_;
};
fs::path ReportTest::root_;

TEST_F(ReportTest, WritesSelfContainedPageWithTheData) {
  const fs::path plan = root_ / "plan";
  const ReportSummary s = write_report(plan, config());
  EXPECT_EQ(s.output, plan / "report.html");
  ASSERT_TRUE(fs::is_regular_file(s.output));
  EXPECT_EQ(s.num_points, 36u);
  EXPECT_EQ(s.num_ok, 35u);
  EXPECT_EQ(s.num_failed, 1u);
  EXPECT_EQ(s.num_clouds, 35u);
  EXPECT_EQ(s.num_cloud_points, 35u * 1500u);
  EXPECT_TRUE(s.warnings.empty()) << s.warnings.front();
  const std::string html = read_text_file(s.output.string());
  EXPECT_EQ(s.bytes, html.size());

  // Nothing is loaded from elsewhere: the markup (outside the inlined scripts, whose strings
  // may mention a URL, like Plotly's unused logo link) has no src/href to a URL.
  std::string markup;
  for (std::size_t pos = 0;;) {
    const std::size_t open = html.find("<script", pos);
    markup += html.substr(pos, open == std::string::npos ? std::string::npos : open - pos);
    if (open == std::string::npos) break;
    const std::size_t tag_end = html.find('>', open);
    markup += html.substr(open, tag_end + 1 - open);  // keep the tag itself (a src= would show)
    pos = html.find("</script>", tag_end);
    ASSERT_NE(pos, std::string::npos);
  }
  EXPECT_LT(markup.size(), 10000u);
  const std::regex external(R"((src|href)\s*=\s*["']?\s*(https?:)?//)", std::regex::icase);
  EXPECT_FALSE(std::regex_search(markup, external));
  EXPECT_EQ(markup.find("http"), std::string::npos);
  EXPECT_EQ(html.find("<script src"), std::string::npos);
  EXPECT_EQ(html.find("<link "), std::string::npos);
  EXPECT_EQ(html.find("{{"), std::string::npos) << "a template placeholder was left";
  // The libraries are inlined.
  EXPECT_NE(html.find("window.Plotly"), std::string::npos);
  EXPECT_NE(html.find("OrbitControls"), std::string::npos);

  const json d = embedded_data(html);
  EXPECT_EQ(d["results"]["points"].size(), 36u);
  EXPECT_NE(html.find("p0035"), std::string::npos);
  EXPECT_EQ(d["color_mode"], "error");
  // Axes keep the sweep's order (the page's selectors list them so).
  std::vector<std::string> axes;
  for (const auto& [k, v] : d["results"]["axes"].items()) axes.push_back(k);
  EXPECT_EQ(axes, (std::vector<std::string>{"object", "aperture_deg", "spacing_m", "method"}));
  EXPECT_EQ(d["clouds"].size(), 35u);
  EXPECT_FALSE(d["clouds"].contains("p0035"));  // the failed point has no cloud
  EXPECT_EQ(d["meshes"].size(), 2u);
  EXPECT_TRUE(d["sweep_yaml"].is_string());
  EXPECT_EQ(d["extras"]["p0000"]["object_metrics"].size(), 2u);

  // The embedded points and errors are the cloud's: positions round-trip exactly, and the
  // median of the embedded distances is the median error evaluate() measured on the same cloud.
  for (const std::string id : {"p0000", "p0017", "p0030"}) {
    const json& c = d["clouds"][id];
    const std::vector<float> xyz = floats(c["xyz"]);
    const std::vector<float> err = floats(c["err"]);
    ASSERT_EQ(xyz.size(), 3 * 1500u);
    ASSERT_EQ(err.size(), 1500u);
    const PointCloud cloud = read_ply((plan / "points" / id / "cloud.ply").string());
    for (std::size_t k = 0; k < cloud.size(); ++k) {
      ASSERT_EQ(xyz[3 * k + 2], cloud.points[k].z());
    }
    std::vector<float> sorted = err;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const json* point = nullptr;
    for (const auto& p : d["results"]["points"]) {
      if (p["id"] == id) point = &p;
    }
    ASSERT_NE(point, nullptr);
    EXPECT_NEAR(sorted[sorted.size() / 2], (*point)["metrics"]["median_error_m"].get<double>(),
                2e-4)
        << id;
  }
}

TEST_F(ReportTest, SubsamplesLargeCloudsDeterministically) {
  const fs::path plan = copy_plan("subsample");
  ReportConfig cfg = config();
  cfg.max_points_per_cloud = 400;
  cfg.output = root_ / "subsample_a.html";
  write_report(plan, cfg);
  cfg.output = root_ / "subsample_b.html";
  const ReportSummary s = write_report(plan, cfg);
  EXPECT_EQ(s.num_cloud_points, 35u * 400u);
  const json a = embedded_data(read_text_file((root_ / "subsample_a.html").string()));
  const json b = embedded_data(read_text_file((root_ / "subsample_b.html").string()));
  EXPECT_EQ(a["clouds"], b["clouds"]);  // same seed, same subsets
  EXPECT_EQ(a["clouds"]["p0001"]["num_shown"], 400);
  EXPECT_EQ(a["clouds"]["p0001"]["num_total"], 1500);
  // The subset is a subset: each shown point is a point of the cloud.
  const PointCloud cloud = read_ply((plan / "points/p0001/cloud.ply").string());
  const std::vector<float> xyz = floats(a["clouds"]["p0001"]["xyz"]);
  for (std::size_t k = 0; k < 400; k += 37) {
    const Eigen::Vector3f q(xyz[3 * k], xyz[3 * k + 1], xyz[3 * k + 2]);
    const bool found = std::any_of(cloud.points.begin(), cloud.points.end(),
                                   [&](const Eigen::Vector3f& p) { return p == q; });
    EXPECT_TRUE(found) << "shown point " << k;
  }
  // A total budget shares itself evenly over the clouds.
  cfg.max_points_per_cloud = 60000;
  cfg.max_points_total = 3500;
  cfg.output = root_ / "subsample_c.html";
  EXPECT_EQ(write_report(plan, cfg).num_cloud_points, 3500u);
}

TEST_F(ReportTest, SimplifiesOnlyLargeMeshesForDisplay) {
  const fs::path plan = root_ / "bigmesh";
  FixtureOptions opt;
  opt.cloud_points = 200;
  opt.sphere_segments = 200;  // 2·200·100 triangles
  make_plan_dir(plan, opt);
  const std::size_t full = load_mesh((plan / "truth/sphere.ply").string()).triangles.size();
  ASSERT_GT(full, 30000u);
  ReportConfig cfg = config();
  cfg.max_mesh_triangles = 5000;
  const json d = embedded_data(read_text_file(write_report(plan, cfg).output.string()));
  const json& m = d["meshes"]["sphere"];
  EXPECT_EQ(m["num_triangles_full"], full);
  EXPECT_LE(m["num_triangles"].get<std::size_t>(), 5000u);
  EXPECT_GT(m["num_triangles"].get<std::size_t>(), 500u);  // still a sphere, not a few triangles
  // The simplified vertices stay near the sphere (radius 0.5 m about (0, 0, 0.5)).
  const std::vector<float> v = floats(m["vertices"]);
  for (std::size_t k = 0; k < v.size(); k += 3) {
    const double r = Eigen::Vector3d(v[k], v[k + 1], v[k + 2] - 0.5).norm();
    ASSERT_NEAR(r, 0.5, 0.03);
  }
  // The tank (below the limit) is embedded whole.
  EXPECT_EQ(d["meshes"]["tank"]["num_triangles"], d["meshes"]["tank"]["num_triangles_full"]);
  // The errors are measured on the full mesh: the median is the one evaluate() measured.
  std::vector<float> err = floats(d["clouds"]["p0000"]["err"]);
  std::nth_element(err.begin(), err.begin() + err.size() / 2, err.end());
  EXPECT_NEAR(err[err.size() / 2],
              d["results"]["points"][0]["metrics"]["median_error_m"].get<double>(), 2e-4);
}

void expect_error(const std::function<void()>& f, const std::vector<std::string>& parts) {
  try {
    f();
    ADD_FAILURE() << "no error thrown";
  } catch (const Error& e) {
    for (const auto& p : parts) {
      EXPECT_NE(std::string(e.what()).find(p), std::string::npos)
          << "'" << e.what() << "' does not mention '" << p << "'";
    }
  }
}

TEST_F(ReportTest, BadInputsGiveClearErrorsAndNoPage) {
  const ReportConfig cfg = config();
  // Missing directory, missing results.json.
  expect_error([&] { write_report(root_ / "nowhere", cfg); }, {"nowhere", "does not exist"});
  const fs::path empty = root_ / "empty";
  fs::create_directories(empty);
  expect_error([&] { write_report(empty, cfg); }, {"results.json", "sonar3d plan"});
  EXPECT_FALSE(fs::exists(empty / "report.html"));

  // Malformed JSON names the file and where.
  const fs::path bad = copy_plan("malformed");
  write_text_file((bad / "results.json").string(), "{\"version\": 1, \"points\": [ {\"id\": ");
  expect_error([&] { write_report(bad, cfg); }, {(bad / "results.json").string(), "malformed"});
  EXPECT_FALSE(fs::exists(bad / "report.html"));

  // Structurally wrong files name the entry at fault.
  write_text_file((bad / "results.json").string(), "{\"points\": {}}");
  expect_error([&] { write_report(bad, cfg); }, {"'points' must be an array"});
  write_text_file((bad / "results.json").string(),
                  "{\"points\": [{\"id\": \"a\", \"status\": "
                  "\"ok\"}, {\"status\": \"ok\"}]}");
  expect_error([&] { write_report(bad, cfg); }, {"points[1]", "'id'"});
  write_text_file((bad / "results.json").string(),
                  "{\"points\": [{\"id\": \"a\", \"status\": \"ok\", \"cloud\": 3}]}");
  expect_error([&] { write_report(bad, cfg); }, {"points[0]", "'cloud'"});

  // Missing web assets say how to get them.
  ReportConfig no_web = cfg;
  no_web.web_dir = root_ / "no_web";
  expect_error([&] { write_report(root_ / "plan", no_web); }, {"install-deps.sh", "no_web"});

  // Invalid config names the field.
  ReportConfig zero = cfg;
  zero.max_points_per_cloud = 0;
  expect_error([&] { write_report(root_ / "plan", zero); }, {"max_points", "--max-points", ">= 1"});
  expect_error([] { parse_report_color("rainbow"); }, {"rainbow", "error or height"});
}

TEST_F(ReportTest, MissingCloudOrTruthIsAWarningNotAnError) {
  const fs::path plan = copy_plan("missing");
  fs::remove(plan / "points/p0003/cloud.ply");
  fs::remove(plan / "truth/tank.ply");
  const ReportSummary s = write_report(plan, config());
  EXPECT_EQ(s.num_clouds, 34u);
  ASSERT_EQ(s.warnings.size(), 2u);
  const std::string all = s.warnings[0] + "\n" + s.warnings[1];
  EXPECT_NE(all.find("p0003"), std::string::npos);
  EXPECT_NE(all.find("tank.ply"), std::string::npos);
  const json d = embedded_data(read_text_file(s.output.string()));
  EXPECT_EQ(d["extras"]["p0003"]["cloud_status"], "missing");
  EXPECT_FALSE(d["clouds"].contains("p0003"));
  EXPECT_FALSE(d["meshes"].contains("tank"));
  EXPECT_TRUE(d["clouds"]["p0020"]["err"].is_null());    // a tank point: height only
  EXPECT_TRUE(d["clouds"]["p0000"]["err"].is_string());  // a sphere point keeps its errors
  EXPECT_EQ(d["warnings"].size(), 2u);                   // shown on the page too
}

TEST_F(ReportTest, CommandLine) {
  const fs::path plan = copy_plan("cli");
  const std::string cli = SONAR3D_CLI;
  if (!fs::exists(cli)) GTEST_SKIP() << "CLI not built: " << cli;
  const std::string web = " --web-dir '" + kWebDir.string() + "'";
  const std::string out = (root_ / "cli.html").string();
  EXPECT_EQ(std::system((cli + " report '" + plan.string() + "' -o '" + out + "'" + web +
                         " --color height --max-points 100 -q > /dev/null")
                            .c_str()),
            0);
  const json d = embedded_data(read_text_file(out));
  EXPECT_EQ(d["color_mode"], "height");
  EXPECT_EQ(d["clouds"]["p0000"]["num_shown"], 100);
  const fs::path log = root_ / "cli_err.txt";
  EXPECT_NE(std::system((cli + " report '" + (root_ / "nowhere").string() + "'" + web + " 2> '" +
                         log.string() + "'")
                            .c_str()),
            0);
  EXPECT_NE(read_text_file(log.string()).find("does not exist"), std::string::npos);
}

// The page in a real browser: web/test_report.mjs (Playwright driving Debian's Chromium).
TEST_F(ReportTest, RendersInHeadlessChromium) {
  if (std::getenv("SONAR3D_SKIP_BROWSER_TEST") != nullptr) {
    GTEST_SKIP() << "SONAR3D_SKIP_BROWSER_TEST is set";
  }
  const fs::path plan = copy_plan("browser");
  const ReportSummary s = write_report(plan, config());
  run_browser_test(s.output, root_ / "report_page.png", "");
}

// An axis that mixes numbers and a level (snr_db: [none, 30, 20, 10], none = noise-free, as in
// data/sweeps/snr.yaml) is offered as x axis and plotted to scale with "none" apart; strings
// (object) and booleans (zero_mean) plot as categories; a failed point is left out.
TEST_F(ReportTest, MixedNumberAndLevelAxisPlotsInHeadlessChromium) {
  if (std::getenv("SONAR3D_SKIP_BROWSER_TEST") != nullptr) {
    GTEST_SKIP() << "SONAR3D_SKIP_BROWSER_TEST is set";
  }
  const json axes = {{"object", {"sphere", "tank"}},
                     {"snr_db", {nullptr, 30.0, 20.0, 10.0}},
                     {"zero_mean", {true, false}}};
  std::vector<json> grid;
  for (const auto& o : axes["object"])
    for (const auto& snr : axes["snr_db"])
      for (const auto& z : axes["zero_mean"])
        grid.push_back({{"object", o}, {"snr_db", snr}, {"zero_mean", z}});
  const fs::path plan = make_small_plan_dir(root_ / "mixed", axes, grid, [](const json& p) {
    return p["object"] == "tank" && p["snr_db"] == 10.0 && p["zero_mean"] == false;
  });
  const ReportSummary s = write_report(plan, config());
  EXPECT_EQ(s.num_points, 16u);
  EXPECT_EQ(s.num_failed, 1u);
  // The page gets the axis as written: null first, then the numbers.
  const json d = embedded_data(read_text_file(s.output.string()));
  EXPECT_EQ(d["results"]["axes"]["snr_db"], json({nullptr, 30.0, 20.0, 10.0}));
  run_browser_test(s.output, root_ / "mixed_page.png", "--mixed-axis snr_db");
}

// A sweep over a single axis plots against it with one line; a sweep where every configuration
// failed says so instead of drawing empty plots, and lists the messages.
TEST_F(ReportTest, SingleAxisAndAllFailedSweepsInHeadlessChromium) {
  if (std::getenv("SONAR3D_SKIP_BROWSER_TEST") != nullptr) {
    GTEST_SKIP() << "SONAR3D_SKIP_BROWSER_TEST is set";
  }
  const json single_axes = {{"spacing_m", {0.05, 0.01, 0.02}}};
  std::vector<json> grid;
  for (const auto& v : single_axes["spacing_m"]) grid.push_back({{"spacing_m", v}});
  const fs::path single =
      make_small_plan_dir(root_ / "single", single_axes, grid, [](const json&) { return false; });
  run_browser_test(write_report(single, config()).output, root_ / "single_page.png", "");

  const json failed_axes = {{"method", {"carve", "deconv"}}, {"standoff_m", {8.0, 9.0}}};
  grid.clear();
  for (const auto& m : failed_axes["method"])
    for (const auto& r : failed_axes["standoff_m"])
      grid.push_back({{"method", m}, {"standoff_m", r}});
  const fs::path all_failed =
      make_small_plan_dir(root_ / "allfailed", failed_axes, grid, [](const json&) { return true; });
  const ReportSummary s = write_report(all_failed, config());
  EXPECT_EQ(s.num_failed, 4u);
  EXPECT_EQ(s.num_clouds, 0u);
  run_browser_test(s.output, root_ / "allfailed_page.png", "--all-failed");
}

// ---------------------------------------------------------------- scene pages
// Map, world, change directories and PLY files (docs/report.md, "Scene pages"), built here per
// the agreed formats (docs/formats.md): the page embeds what the inputs hold, and headless
// Chromium draws the right layers with the right counts and colours.

using Rgb = std::array<std::uint8_t, 3>;

// A binary little-endian PLY triangle mesh with optional uchar colours, as `sonar3d world` writes
// its seabed and models.
void write_mesh_ply(const fs::path& path, const TriangleMesh& m, const std::vector<Rgb>& rgb = {}) {
  fs::create_directories(path.parent_path());
  std::ofstream f(path, std::ios::binary);
  f << "ply\nformat binary_little_endian 1.0\nelement vertex " << m.vertices.size()
    << "\nproperty float x\nproperty float y\nproperty float z\n";
  if (!rgb.empty()) f << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  f << "element face " << m.triangles.size()
    << "\nproperty list uchar int vertex_indices\nend_header\n";
  for (std::size_t v = 0; v < m.vertices.size(); ++v) {
    f.write(reinterpret_cast<const char*>(m.vertices[v].data()), 12);
    if (!rgb.empty()) f.write(reinterpret_cast<const char*>(rgb[v].data()), 3);
  }
  for (const auto& t : m.triangles) {
    const unsigned char n = 3;
    f.write(reinterpret_cast<const char*>(&n), 1);
    f.write(reinterpret_cast<const char*>(t.data()), 12);
  }
}

// A height-field mesh of nx × ny cells over [0, sx] × [0, sy].
TriangleMesh grid_mesh(int nx, int ny, double sx, double sy) {
  TriangleMesh m;
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) {
      const double x = sx * i / nx, y = sy * j / ny;
      m.vertices.emplace_back(x, y, 0.1 * std::sin(x) * std::cos(y));
    }
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const int a = j * (nx + 1) + i, b = a + 1, c = a + nx + 1, d = c + 1;
      m.triangles.emplace_back(a, b, d);
      m.triangles.emplace_back(a, d, c);
    }
  return m;
}

Eigen::Matrix4d pose_xyz_yaw(double x, double y, double z, double yaw_deg) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translate(Eigen::Vector3d(x, y, z));
  T.rotate(Eigen::AngleAxisd(yaw_deg * M_PI / 180, Eigen::Vector3d::UnitZ()));
  return T.matrix();
}
json flat16(const Eigen::Matrix4d& T) {
  json a = json::array();
  for (int k = 0; k < 16; ++k) a.push_back(T(k / 4, k % 4));
  return a;
}
json rows4(const Eigen::Matrix4d& T) {
  json a = json::array();
  for (int r = 0; r < 4; ++r) a.push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
  return a;
}
TriangleMesh placed(TriangleMesh m, const Eigen::Matrix4d& T) {
  Eigen::Isometry3d iso;
  iso.matrix() = T;
  m.transform(iso);
  return m;
}

const char* kCatalogue =
    "models:\n  - name: tank\n    reference: tank\n    symmetry: full\n"
    "  - name: sphere\n    reference: sphere\n    symmetry: full\n    expected: 2\n";

class SceneReportTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = fs::temp_directory_path() / ("sonar3d_test_scene_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_);
    write_text_file((root_ / "catalogue.yaml").string(), kCatalogue);
    make_map();
    make_world();
    make_changes();
    make_textured();
  }
  static void TearDownTestSuite() {
    if (std::getenv("SONAR3D_KEEP_TEST_OUTPUT") == nullptr) fs::remove_all(root_);
  }
  static ReportConfig config() { return report_test_config(); }

  // A map directory: merged.ply is a bumpy seabed (60 × 40 points) plus the vertices of three
  // placed models; placements.json (4×4 rows, as `sonar3d recognize` writes) places them.
  static void make_map() {
    const fs::path d = root_ / "map";
    fs::create_directories(d);
    poses_ = {pose_xyz_yaw(1.5, 1.0, 0.0, 30), pose_xyz_yaw(4.0, 2.5, 0.0, -75),
              pose_xyz_yaw(3.0, 0.8, 0.0, 0)};
    models_ = {"tank", "tank", "sphere"};
    PointCloud cloud;
    for (int j = 0; j < 40; ++j)
      for (int i = 0; i < 60; ++i) {
        cloud.points.emplace_back(0.1f * i, 0.1f * j, 0.05f * std::sin(0.3f * i));
        cloud.intensity.push_back(0.2f + 0.6f * static_cast<float>(i) / 59);  // rising east
      }
    for (std::size_t k = 0; k < poses_.size(); ++k) {
      const TriangleMesh m =
          placed(models_[k] == "tank" ? make_reference_tank() : make_reference_sphere(), poses_[k]);
      for (std::size_t v = 0; v < m.vertices.size(); v += 7) {
        cloud.points.push_back(m.vertices[v]);
        cloud.intensity.push_back(1.0f);  // the structures echo strongest
      }
    }
    write_ply((d / "merged.ply").string(), cloud);
    map_points_ = cloud.size();
    json list = json::array();
    for (std::size_t k = 0; k < poses_.size(); ++k) {
      list.push_back({{"model", models_[k]},
                      {"method", "2d"},
                      {"T_world_model", rows4(poses_[k])},
                      {"score_m", 0.01 * (k + 1)},
                      {"residual_median_m", k == 1 ? json(nullptr) : json(0.012)},
                      {"residual_mean_m", 0.015}});
    }
    const json pj = {{"format", "sonar3d-placements"},
                     {"version", 1},
                     {"map", "map"},
                     {"catalogue", "catalogue.yaml"},
                     {"placements", list}};
    write_text_file((root_ / "placements.json").string(), pj.dump(2));
  }

  // A world directory: two seabed levels of detail (800 and 200 triangles), a tank with vertex
  // colours and a sphere without, joined by a pipeline.
  static void make_world() {
    const fs::path d = root_ / "world";
    write_mesh_ply(d / "seabed_lod0.ply", grid_mesh(20, 20, 8, 6));
    write_mesh_ply(d / "seabed_lod1.ply", grid_mesh(10, 10, 8, 6));
    const Eigen::Matrix4d Tt = pose_xyz_yaw(2, 2, 0, 20), Ts = pose_xyz_yaw(6, 4, 0, 0);
    const TriangleMesh tank = placed(make_reference_tank(), Tt);
    tank_colors_.clear();
    for (std::size_t v = 0; v < tank.vertices.size(); ++v) {
      tank_colors_.push_back(
          {static_cast<std::uint8_t>(40 + v % 200), 90, static_cast<std::uint8_t>(200 - v % 150)});
    }
    write_mesh_ply(d / "models/tank_0.ply", tank, tank_colors_);
    write_mesh_ply(d / "models/sphere_0.ply", placed(make_reference_sphere(), Ts));
    const json g = {
        {"format", "sonar3d-world"},
        {"version", 1},
        {"objects",
         {{{"id", "tank_0"},
           {"model", "tank"},
           {"kind", "structure"},
           {"T_world_model", flat16(Tt)},
           {"score_m", 0.02},
           {"residual_median_m", 0.011},
           {"file", "models/tank_0.ply"}},
          {{"id", "sphere_0"},
           {"model", "sphere"},
           {"kind", "structure"},
           {"T_world_model", flat16(Ts)},
           {"score_m", 0.03},
           {"residual_median_m", nullptr},
           {"file", "models/sphere_0.ply"}}}},
        {"connections",
         {{{"from", "tank_0"}, {"to", "sphere_0"}, {"kind", "pipeline"}, {"length_m", 4.47}}}},
        {"seabed",
         {{{"lod", 0},
           {"file", "seabed_lod0.ply"},
           {"cell_m", 0.3},
           {"triangles", 800},
           {"bytes", 12000},
           {"median_error_m", 0.01}},
          {{"lod", 1},
           {"file", "seabed_lod1.ply"},
           {"cell_m", 0.6},
           {"triangles", 200},
           {"bytes", 3000},
           {"median_error_m", nullptr}}}},
        {"source", {{"map", "map"}, {"placements", "placements.json"}, {"catalogue", "c.yaml"}}},
        {"bytes_total", 60000},
        {"cloud_bytes", 6000000}};
    write_text_file((d / "graph.json").string(), g.dump(2));
  }

  // A change directory: 40 × 30 points, raised by 0.3 m in one corner, lowered by 0.2 m in
  // another; a tank moved 30 cm and turned 10°, a sphere added, a tank removed, a sphere kept.
  static void make_changes() {
    const fs::path d = root_ / "changes";
    fs::create_directories(d);
    PointCloud c;
    PointProperty change{"change_m", {}};
    for (int j = 0; j < 30; ++j)
      for (int i = 0; i < 40; ++i) {
        c.points.emplace_back(0.1f * i, 0.1f * j, 0.f);
        float v = 0;
        if (i < 8 && j < 8) v = 0.3f;
        if (i > 32 && j > 22) v = -0.2f;
        change.values.push_back(v);
      }
    c.properties.push_back(change);
    write_ply((d / "change_points.ply").string(), c);
    change_points_ = c.size();
    const Eigen::Matrix4d A = pose_xyz_yaw(1, 1, 0, 0), B = pose_xyz_yaw(1.3, 1, 0, 10);
    const json objects = {{{"id", "tank_0"},
                           {"model", "tank"},
                           {"status", "moved"},
                           {"T_world_model_a", flat16(A)},
                           {"T_world_model_b_in_a", flat16(B)},
                           {"shift_m", 0.3},
                           {"turn_deg", 10}},
                          {{"id", "sphere_1"},
                           {"model", "sphere"},
                           {"status", "added"},
                           {"T_world_model_a", nullptr},
                           {"T_world_model_b_in_a", flat16(pose_xyz_yaw(3, 2, 0, 0))},
                           {"shift_m", nullptr},
                           {"turn_deg", nullptr}},
                          {{"id", "tank_1"},
                           {"model", "tank"},
                           {"status", "removed"},
                           {"T_world_model_a", flat16(pose_xyz_yaw(2, 2.5, 0, 45))},
                           {"T_world_model_b_in_a", nullptr},
                           {"shift_m", nullptr},
                           {"turn_deg", nullptr}},
                          {{"id", "sphere_0"},
                           {"model", "sphere"},
                           {"status", "unchanged"},
                           {"T_world_model_a", flat16(pose_xyz_yaw(3.5, 0.5, 0, 0))},
                           {"T_world_model_b_in_a", flat16(pose_xyz_yaw(3.51, 0.5, 0, 0))},
                           {"shift_m", 0.01},
                           {"turn_deg", 0.2}}};
    const json j = {
        {"format", "sonar3d-changes"},
        {"version", 1},
        {"T_a_b", flat16(pose_xyz_yaw(0.2, -0.1, 0, 1))},
        {"registration", {{"method", "elevation-map"}, {"rms_m", 0.012}, {"overlap_cells", 1200}}},
        {"objects", objects},
        {"regions",
         {{{"id", 1},
           {"centroid", {0.35, 0.35, 0}},
           {"area_m2", 0.64},
           {"max_abs_change_m", 0.3},
           {"mean_change_m", 0.3},
           {"kind", "raised"}},
          {{"id", 2},
           {"centroid", {3.65, 2.65, 0}},
           {"area_m2", 0.42},
           {"max_abs_change_m", 0.2},
           {"mean_change_m", -0.2},
           {"kind", "lowered"}}}},
        {"thresholds", {{"shift_m", 0.05}}},
        {"seconds", 1.5}};
    write_text_file((d / "changes.json").string(), j.dump(2));
  }

  // Textured outputs as `sonar3d texture` writes them: a cloud with colours (black: unseen) and
  // a mesh with vertex colours (write_textured_mesh_ply's layout).
  static void make_textured() {
    PointCloud c;
    for (int k = 0; k < 3000; ++k) {  // a 60 × 50 patch of a wavy surface
      const float x = 0.02f * (k % 60), y = 0.02f * (k / 60);
      c.points.emplace_back(x, y, 0.05f * std::sin(8 * x) * std::cos(6 * y));
      c.color.push_back({static_cast<std::uint8_t>(k % 256), static_cast<std::uint8_t>(k / 12),
                         static_cast<std::uint8_t>(k % 3 == 0 ? 0 : 200)});
    }
    write_ply((root_ / "textured_cloud.ply").string(), c);
    TexturedMesh box;  // written by sonar3d texture's own writer
    box.mesh = make_box(1, 0.6, 0.4);
    for (std::size_t v = 0; v < box.mesh.vertices.size(); ++v) {
      box.color.emplace_back(0.1f * (v % 8), 0.5f, 1.f - 0.1f * (v % 8));  // linear RGB
      box.views.push_back(v == 0 ? 0 : 2);  // vertex 0 seen by no frame: black
    }
    write_textured_mesh_ply(root_ / "textured_mesh.ply", box);
  }

  static fs::path root_;
  static std::vector<Eigen::Matrix4d> poses_;
  static std::vector<std::string> models_;
  static std::vector<Rgb> tank_colors_;
  static std::size_t map_points_, change_points_;
};
fs::path SceneReportTest::root_;
std::vector<Eigen::Matrix4d> SceneReportTest::poses_;
std::vector<std::string> SceneReportTest::models_;
std::vector<Rgb> SceneReportTest::tank_colors_;
std::size_t SceneReportTest::map_points_ = 0, SceneReportTest::change_points_ = 0;

const json* layer(const json& data, const std::string& id) {
  for (const auto& l : data["layers"])
    if (l["id"] == id) return &l;
  return nullptr;
}
std::size_t table_rows(const json& data, const std::string& id) {
  for (const auto& t : data["tables"])
    if (t["id"] == id) return t["rows"].size();
  return 0;
}

// Runs test_report.mjs on a scene page with the expectations written beside it.
void run_scene_browser_test(const fs::path& page, const json& expect, const std::string& name) {
  if (std::getenv("SONAR3D_SKIP_BROWSER_TEST") != nullptr) return;
  const fs::path e = page.parent_path() / (name + "_expect.json");
  write_text_file(e.string(), expect.dump(2));
  run_browser_test(page, page.parent_path() / (name + "_page.png"),
                   "--expect '" + e.string() + "'");
}

TEST_F(SceneReportTest, DetectsTheInputByContent) {
  EXPECT_EQ(detect_report_input(root_ / "map"), ReportInput::Map);
  EXPECT_EQ(detect_report_input(root_ / "world"), ReportInput::World);
  EXPECT_EQ(detect_report_input(root_ / "changes"), ReportInput::Changes);
  EXPECT_EQ(detect_report_input(root_ / "textured_cloud.ply"), ReportInput::Ply);
  expect_error([&] { detect_report_input(root_ / "catalogue.yaml"); },
               {"catalogue.yaml", "not a PLY"});
  fs::create_directories(root_ / "nothing");
  expect_error([&] { detect_report_input(root_ / "nothing"); },
               {"results.json", "graph.json", "changes.json", "merged.ply"});
}

// Map + placements: the cloud's points and each placed model in its pose, listed in a table.
TEST_F(SceneReportTest, MapWithPlacementsShowsModelsOverTheCloud) {
  ReportConfig cfg = config();
  cfg.placements = root_ / "placements.json";  // its catalogue is found beside it
  const ReportSummary s = write_report(root_ / "map", cfg);
  EXPECT_EQ(s.input, ReportInput::Map);
  EXPECT_EQ(s.output, root_ / "map" / "report.html");
  const std::string html = read_text_file(s.output.string());
  EXPECT_EQ(html.find("plotly"), std::string::npos) << "scene pages need no Plotly";
  EXPECT_EQ(std::regex_search(html, std::regex(R"((src|href)\s*=\s*["']?https?:)")), false);
  const json d = embedded_data(html);
  EXPECT_EQ(d["kind"], "map");
  ASSERT_EQ(d["layers"].size(), 4u);
  const json* cloud = layer(d, "cloud");
  ASSERT_NE(cloud, nullptr);
  EXPECT_EQ((*cloud)["count"].get<std::size_t>(), map_points_);
  // The cloud's intensities go with its points: a colour mode of their own.
  EXPECT_EQ((*cloud)["color_modes"], json({"height", "intensity"}));
  const std::vector<float> in = floats((*cloud)["intensity"]);
  ASSERT_EQ(in.size(), map_points_);
  EXPECT_FLOAT_EQ(in[0], 0.2f);
  EXPECT_FLOAT_EQ(in.back(), 1.0f);
  const PointCloud merged = read_ply((root_ / "map/merged.ply").string());
  const std::vector<float> xyz = floats((*cloud)["xyz"]);
  ASSERT_EQ(xyz.size(), 3 * merged.size());
  for (std::size_t k = 0; k < merged.size(); k += 97) {
    for (int c = 0; c < 3; ++c) EXPECT_EQ(xyz[3 * k + c], merged.points[k][c]);
  }
  const Catalogue cat = read_catalogue((root_ / "catalogue.yaml").string());
  json expect_layers = json::array(
      {{{"id", "cloud"}, {"type", "points"}, {"count", map_points_}, {"visible", true}}});
  for (std::size_t k = 0; k < poses_.size(); ++k) {
    const json* m = layer(d, "placement_" + std::to_string(k));
    ASSERT_NE(m, nullptr);
    const TriangleMesh model = load_catalogue_mesh(cat, cat.models[models_[k] == "tank" ? 0 : 1]);
    EXPECT_EQ((*m)["count"].get<std::size_t>(), model.triangles.size());
    // The model's first vertex, placed by T_world_model.
    const std::vector<float> v = floats((*m)["xyz"]);
    const Eigen::Vector3d expected =
        (poses_[k] * model.vertices[0].cast<double>().homogeneous()).head<3>();
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(v[c], expected[c], 1e-5);
    EXPECT_LT((*m)["opacity"].get<double>(), 1.0);
    expect_layers.push_back(
        {{"id", (*m)["id"]}, {"type", "mesh"}, {"count", (*m)["count"]}, {"visible", true}});
  }
  EXPECT_EQ(table_rows(d, "placements"), 3u);
  // Per catalogue model, expected (the catalogue's `expected`) and found.
  const json* per_model = nullptr;
  for (const auto& t : d["tables"]) {
    if (t["id"] == "models") per_model = &t;
  }
  ASSERT_NE(per_model, nullptr);
  ASSERT_EQ((*per_model)["rows"].size(), 2u);
  EXPECT_EQ((*per_model)["rows"][0],
            json({"tank", nullptr, 2, "tank: 2 (expected count not given)"}));
  EXPECT_EQ((*per_model)["rows"][1], json({"sphere", 2, 1, "sphere: 1 of 2"}));
  bool card_found = false;
  for (const auto& c : d["cards"]) {
    if (c["k"] == "found of expected") card_found = c["v"] == "1 of 2";
  }
  EXPECT_TRUE(card_found) << d["cards"];
  EXPECT_EQ(s.num_table_rows, 5u);
  // Same model, same colour; another model, another.
  EXPECT_EQ((*layer(d, "placement_0"))["color"], (*layer(d, "placement_1"))["color"]);
  EXPECT_NE((*layer(d, "placement_0"))["color"], (*layer(d, "placement_2"))["color"]);
  const json expect = {{"kind", "map"},
                       {"layers", expect_layers},
                       {"tables", {{"placements", 3}}},
                       {"colors",
                        {{{"layer", "placement_0"}, {"index", 0}, {"rgb", {31, 119, 180}}},
                         {{"layer", "placement_2"}, {"index", 0}, {"rgb", {214, 39, 40}}}}},
                       {"focus", {{"table", "placements"}, {"layer", "placement_0"}}},
                       {"intensity", {{"layer", "cloud"}, {"low", 0}, {"high", map_points_ - 1}}},
                       {"mode_change", false}};
  run_scene_browser_test(s.output, expect, "map");
}

// A map directory as `sonar3d map --method drift` writes it: summary.json's swaths (offsets,
// drift rates) and ties become tables, and the dataset's navigation against
// navigation_corrected.tum a picture (axes in metres, scale bar, north arrow) and the
// correction's median and maximum.
TEST_F(SceneReportTest, MapPageShowsSwathsTiesDriftAndTheNavigationCorrection) {
  const fs::path dir = root_ / "map_drift", ds = root_ / "map_drift_dataset";
  fs::create_directories(dir);
  fs::create_directories(ds);
  PointCloud cloud;
  for (int i = 0; i < 50; ++i) cloud.points.emplace_back(0.2f * i, 0.1f * (i % 7), 0.0f);
  write_ply((dir / "merged.ply").string(), cloud);
  // Logged: 0.5 m/s east for 20 s; corrected: 0.1 m + 0.01 m/s · t further east.
  Trajectory before, after;
  for (int k = 0; k <= 20; ++k) {
    const double t = k;
    before.push_back(t, Eigen::Isometry3d(Eigen::Translation3d(0.5 * t, 2.0, -1.0)));
    after.push_back(t,
                    Eigen::Isometry3d(Eigen::Translation3d(0.5 * t + 0.1 + 0.01 * t, 2.0, -1.0)));
  }
  write_tum((ds / "navigation.tum").string(), before);
  write_tum((dir / "navigation_corrected.tum").string(), after);
  const json summary = {{"dataset", ds.string()},
                        {"method", "drift"},
                        {"swaths",
                         {{{"frames", {0, 99}},
                           {"time_s", {0.0, 10.0}},
                           {"points", 1200},
                           {"map_cells", 300},
                           {"offset_m", {0.1, 0.0, 0.0}},
                           {"seconds", 0.5},
                           {"rate_mps", {0.01, -0.002}}},
                          {{"frames", {100, 199}},
                           {"time_s", {10.0, 20.0}},
                           {"points", 1100},
                           {"map_cells", 280},
                           {"offset_m", {0.2, 0.0, 0.01}},
                           {"seconds", 0.4},
                           {"rate_mps", {0.01, 0.003}}}}},
                        {"ties",
                         {{{"reference", 0},
                           {"moving", 1},
                           {"shift_m", {0.1, 0.0, 0.01}},
                           {"score_m", 0.02},
                           {"overlap_cells", 150},
                           {"confidence", 0.9},
                           {"used", true},
                           {"residual_m", 0.004},
                           {"seconds", 0.1},
                           {"time_reference_s", 5.0},
                           {"time_moving_s", 15.0}},
                          {{"reference", 1},
                           {"moving", 0},
                           {"shift_m", {-0.1, 0.0, 0.0}},
                           {"score_m", 0.05},
                           {"overlap_cells", 40},
                           {"confidence", 0.2},
                           {"used", false},
                           {"residual_m", 0.03},
                           {"seconds", 0.1}}}}};
  write_text_file((dir / "summary.json").string(), summary.dump(2));
  const ReportSummary s = write_report(dir, config());
  const json d = embedded_data(read_text_file(s.output.string()));
  const json* swaths = nullptr;
  const json* ties = nullptr;
  for (const auto& t : d["tables"]) {
    if (t["id"] == "swaths") swaths = &t;
    if (t["id"] == "ties") ties = &t;
  }
  ASSERT_NE(swaths, nullptr);
  ASSERT_NE(ties, nullptr);
  ASSERT_EQ((*swaths)["rows"].size(), 2u);
  EXPECT_EQ((*swaths)["rows"][1],
            json({1, 100, 199, 10.0, 20.0, 1100, 0.2, 0.0, 0.01, 0.01, 0.003}));
  EXPECT_NE((*swaths)["title"].get<std::string>().find("drift rates"), std::string::npos);
  EXPECT_EQ((*swaths)["columns"][9], "drift rate x [m/s]");
  ASSERT_EQ((*ties)["rows"].size(), 2u);
  EXPECT_EQ((*ties)["rows"][0],
            json({0, 1, 5.0, 15.0, 0.1, 0.0, 0.01, 0.02, 150, 0.9, "yes", 0.004}));
  EXPECT_EQ((*ties)["rows"][1][10], "no");
  std::map<std::string, json> cards;
  for (const auto& c : d["cards"]) cards[c["k"].get<std::string>()] = c["v"];
  EXPECT_EQ(cards["ties used"], "1 of 2");
  EXPECT_EQ(cards["map method"], "drift");
  // The correction grows from 0.1 m (t = 0) to 0.3 m (t = 20); its median is at t = 10.
  EXPECT_NEAR(cards["navigation correction, median [m]"].get<double>(), 0.2, 1e-9);
  EXPECT_NEAR(cards["navigation correction, max [m]"].get<double>(), 0.3, 1e-9);
  ASSERT_EQ(d["figures"].size(), 1u);
  const std::string svg = d["figures"][0]["svg"];
  for (const char* part :
       {"class=\"track-before\"", "class=\"track-after\"", "class=\"north-arrow\"",
        "class=\"scale-bar\"", "x [m] (East)", "y [m] (North)", " m</text>"}) {
    EXPECT_NE(svg.find(part), std::string::npos) << part;
  }
  // The tracks' first vertices sit where their first poses are: x = 0 and 0.1 m on a common
  // equal-scale frame, so the corrected track starts right of the logged one at the same height.
  auto first_vertex = [&](const std::string& cls) {
    const std::size_t at = svg.find("class=\"" + cls + "\"");
    const std::size_t p = svg.find("points=\"", at) + 8;
    double x = 0, y = 0;
    std::sscanf(svg.c_str() + p, "%lf,%lf", &x, &y);
    return Eigen::Vector2d(x, y);
  };
  const Eigen::Vector2d b0 = first_vertex("track-before"), a0 = first_vertex("track-after");
  EXPECT_GT(a0.x(), b0.x());
  EXPECT_NEAR(a0.y(), b0.y(), 0.05);
  EXPECT_TRUE(d["warnings"].empty()) << d["warnings"];
  const json expect = {
      {"kind", "map"},
      {"layers", {{{"id", "cloud"}, {"type", "points"}, {"count", 50}, {"visible", true}}}},
      {"tables", {{"swaths", 2}, {"ties", 2}}},
      {"figures", {"track"}},
      {"mode_change", false}};
  run_scene_browser_test(s.output, expect, "map_drift");
}

// World model: seabed levels of detail (one shown at a time), the models (the tank in its vertex
// colours), the connection as a line, the graph as tables.
TEST_F(SceneReportTest, WorldShowsSeabedModelsAndConnections) {
  const ReportSummary s = write_report(root_ / "world", config());
  EXPECT_EQ(s.input, ReportInput::World);
  const json d = embedded_data(read_text_file(s.output.string()));
  ASSERT_EQ(d["layers"].size(), 5u);
  EXPECT_EQ((*layer(d, "seabed_lod0"))["count"], 800);
  EXPECT_EQ((*layer(d, "seabed_lod0"))["visible"], false);
  EXPECT_EQ((*layer(d, "seabed_lod1"))["count"], 200);
  EXPECT_EQ((*layer(d, "seabed_lod1"))["visible"], true);  // the coarsest first
  const json* tank = layer(d, "object_tank_0");
  ASSERT_NE(tank, nullptr);
  const std::vector<unsigned char> rgb = unbase64((*tank)["rgb"]);
  ASSERT_EQ(rgb.size(), 3 * tank_colors_.size());
  for (std::size_t v = 0; v < tank_colors_.size(); v += 13) {
    for (int c = 0; c < 3; ++c) EXPECT_EQ(rgb[3 * v + c], tank_colors_[v][c]);
  }
  EXPECT_TRUE((*layer(d, "object_sphere_0"))["rgb"].is_null());
  const json* lines = layer(d, "connections");
  ASSERT_NE(lines, nullptr);
  EXPECT_EQ((*lines)["count"], 1);
  const std::vector<float> ends = floats((*lines)["xyz"]);
  ASSERT_EQ(ends.size(), 6u);
  // From centre to centre of the placed models' bounding boxes.
  auto box_centre = [&](const char* file) {
    Eigen::AlignedBox3f b;
    for (const auto& p : read_ply((root_ / "world" / file).string()).points) b.extend(p);
    return Eigen::Vector3f(b.center());
  };
  const Eigen::Vector3f ct = box_centre("models/tank_0.ply"),
                        cs = box_centre("models/sphere_0.ply");
  for (int i = 0; i < 3; ++i) {
    EXPECT_FLOAT_EQ(ends[i], ct[i]);
    EXPECT_FLOAT_EQ(ends[3 + i], cs[i]);
  }
  EXPECT_NEAR(ends[0], 2, 0.1);  // the tank at (2, 2), the sphere at (6, 4)
  EXPECT_NEAR(ends[3], 6, 0.1);
  EXPECT_NEAR(ends[4], 4, 0.1);
  EXPECT_EQ(table_rows(d, "objects"), 2u);
  EXPECT_EQ(table_rows(d, "connections"), 1u);
  EXPECT_EQ(table_rows(d, "seabed"), 2u);
  auto L = [&](const std::string& id, const char* type, bool visible) {
    return json{
        {"id", id}, {"type", type}, {"count", (*layer(d, id))["count"]}, {"visible", visible}};
  };
  const json expect = {{"kind", "world"},
                       {"layers",
                        {L("seabed_lod0", "mesh", false), L("seabed_lod1", "mesh", true),
                         L("object_tank_0", "mesh", true), L("object_sphere_0", "mesh", true),
                         L("connections", "lines", true)}},
                       {"tables", {{"objects", 2}, {"connections", 1}, {"seabed", 2}}},
                       {"groups", {{"seabed", {"seabed_lod0", "seabed_lod1"}}}},
                       {"colors",
                        {{{"layer", "object_tank_0"},
                          {"index", 5},
                          {"rgb", {tank_colors_[5][0], tank_colors_[5][1], tank_colors_[5][2]}}},
                         {{"layer", "object_sphere_0"}, {"index", 0}, {"rgb", {214, 39, 40}}},
                         {{"layer", "connections"}, {"index", 0}, {"rgb", {255, 127, 14}}}}},
                       {"focus", {{"table", "objects"}, {"layer", "object_tank_0"}}},
                       {"mode_change", false}};
  run_scene_browser_test(s.output, expect, "world");
}

// Changes: the points on a diverging scale (raised red, lowered blue, unchanged white), each
// object's markers before/after, and with a catalogue the models before and after.
TEST_F(SceneReportTest, ChangesShowPointsObjectsAndRegions) {
  {
    const ReportSummary s = write_report(root_ / "changes", config());
    const json d = embedded_data(read_text_file(s.output.string()));
    ASSERT_EQ(d["layers"].size(), 2u);  // no catalogue: points and markers only
    // moved: 2 markers of 4 strokes + the joining line; added, removed, unchanged: 4 each.
    EXPECT_EQ((*layer(d, "markers"))["count"], 9 + 4 + 4 + 4);
  }
  ReportConfig cfg = config();
  cfg.catalogue = root_ / "catalogue.yaml";
  cfg.output = root_ / "changes_page.html";
  const ReportSummary s = write_report(root_ / "changes", cfg);
  const json d = embedded_data(read_text_file(s.output.string()));
  // + before/after of the moved tank, after of the added sphere, before of the removed tank and
  // the unchanged sphere.
  ASSERT_EQ(d["layers"].size(), 7u);
  const json* pts = layer(d, "change_points");
  EXPECT_EQ((*pts)["count"].get<std::size_t>(), change_points_);
  EXPECT_EQ((*pts)["color_modes"], json({"change", "height"}));
  const std::vector<float> ch = floats((*pts)["change"]);
  ASSERT_EQ(ch.size(), change_points_);
  EXPECT_FLOAT_EQ(ch[0], 0.3f);
  EXPECT_FLOAT_EQ(ch[change_points_ - 1], -0.2f);
  EXPECT_EQ(table_rows(d, "objects"), 4u);
  EXPECT_EQ(table_rows(d, "regions"), 2u);
  json expect_layers = json::array();
  for (const auto& l : d["layers"]) {
    expect_layers.push_back(
        {{"id", l["id"]}, {"type", l["type"]}, {"count", l["count"]}, {"visible", true}});
  }
  const json expect = {
      {"kind", "changes"},
      {"layers", expect_layers},
      {"tables", {{"objects", 4}, {"regions", 2}}},
      {"colors",
       {{{"layer", "change_points"}, {"index", 0}, {"hue", "red"}},
        {{"layer", "change_points"}, {"index", change_points_ - 1}, {"hue", "blue"}},
        {{"layer", "change_points"}, {"index", 20 * 40 + 20}, {"hue", "white"}}}},
      {"mode_change", true}};
  run_scene_browser_test(s.output, expect, "changes");
}

// The rows of a page's table.
json table(const json& data, const std::string& id) {
  for (const auto& t : data["tables"])
    if (t["id"] == id) return t["rows"];
  return json::array();
}

// Issue 28: a world whose sphere is an unconfirmed placement (confidence 0.3 under the world's
// 0.5): drawn grey and named so, listed with its confidence and status, counted on a card; a
// graph.json naming it in a connection (which sonar3d world never writes) is one error line.
TEST_F(SceneReportTest, WorldShowsUnconfirmedObjectsWithoutConnections) {
  const fs::path w = root_ / "world_unconfirmed";
  fs::remove_all(w);
  fs::copy(root_ / "world", w, fs::copy_options::recursive);
  fs::remove(w / "report.html");
  const std::string graph = (w / "graph.json").string();
  json g = json::parse(read_text_file(graph));
  g["min_confidence"] = 0.5;
  g["objects"][0]["confidence"] = 0.9;
  g["objects"][0]["confirmed"] = true;
  g["objects"][1]["confidence"] = 0.3;
  g["objects"][1]["confirmed"] = false;
  const json connections = g["connections"];
  g["connections"] = json::array();
  write_text_file(graph, g.dump());
  const ReportSummary s = write_report(w, config());
  const json d = embedded_data(read_text_file(s.output.string()));
  const json* sphere = layer(d, "object_sphere_0");
  ASSERT_NE(sphere, nullptr);
  EXPECT_EQ((*sphere)["name"], "sphere_0 (unconfirmed)");
  EXPECT_EQ((*layer(d, "object_tank_0"))["name"], "tank_0");
  EXPECT_EQ(layer(d, "connections"), nullptr);
  const json rows = table(d, "objects");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0][10], "confirmed");
  EXPECT_DOUBLE_EQ(rows[1][9].get<double>(), 0.3);
  EXPECT_EQ(rows[1][10], "unconfirmed");
  bool card = false;
  for (const auto& c : d["cards"]) card |= c["k"] == "unconfirmed" && c["v"] == 1;
  EXPECT_TRUE(card) << d["cards"];

  fs::remove(s.output);
  g["connections"] = connections;  // tank_0 - sphere_0
  write_text_file(graph, g.dump());
  expect_error([&] { write_report(w, config()); },
               {graph, "connections[0]", "'to'", "unconfirmed object ('sphere_0')"});
  g["connections"] = json::array();
  g["objects"][1]["confidence"] = 1.5;
  write_text_file(graph, g.dump());
  expect_error([&] { write_report(w, config()); }, {graph, "objects[1]", "'confidence'", "[0, 1]"});
}

// Issue 28: the change directory `sonar3d diff` writes for a pair where a recognition appears in
// one survey only (a tank recognised in A, missed in B, over a site that did not change) is read
// by report: the object is "uncertain", drawn where A placed it, with why; and a changes.json of
// an older diff (that object written "unchanged" with B's pose null) is read as uncertain too.
TEST_F(SceneReportTest, ChangesWithARecognitionInOneSurveyOnly) {
  // The same bumpy 6 × 5 m site in both surveys, B's world offset by a navigation error.
  auto site = [](double x, double y) {
    double z = 0.15 * std::sin(0.9 * x) * std::cos(0.7 * y) + 0.05 * std::sin(2.1 * x + 1.3 * y);
    for (const auto& r : {std::array<double, 3>{1.5, 1.2, 0.2}, {4.2, 3.5, 0.15}, {2.8, 0.6, 0.1}})
      z += r[2] * std::exp(-((x - r[0]) * (x - r[0]) + (y - r[1]) * (y - r[1])) / 0.05);
    return z;
  };
  Eigen::Isometry3d T_b_a = Eigen::Isometry3d::Identity();
  T_b_a.linear() = Eigen::AngleAxisd(0.8 * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T_b_a.translation() = Eigen::Vector3d(0.12, -0.08, 0.03);
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0, 0.004);
  PointCloud a, b;
  for (double x = 0; x <= 6; x += 0.03)
    for (double y = 0; y <= 5; y += 0.03) {
      a.points.emplace_back(x, y, site(x, y) + noise(rng));
      b.points.push_back((T_b_a * Eigen::Vector3d(x, y, site(x, y) + noise(rng))).cast<float>());
    }
  const Catalogue cat = read_catalogue((root_ / "catalogue.yaml").string());
  const Eigen::Isometry3d T_tank(pose_xyz_yaw(3.5, 2.5, site(3.5, 2.5), 0));
  const std::vector<SurveyPlacement> pa{{"tank", T_tank}};
  ChangeConfig cc;
  cc.registration.num_threads = 2;
  const ChangeResult r = diff_surveys(a, b, pa, {}, catalogue_object_models(cat, {"tank"}), cc);
  ASSERT_EQ(r.objects.size(), 1u);
  ASSERT_EQ(r.objects[0].status, ObjectStatus::Uncertain) << r.objects[0].reason;
  const fs::path dir = root_ / "one_survey";
  fs::remove_all(dir);
  write_change_directory(dir.string(), r);

  ReportConfig cfg = config();
  cfg.catalogue = root_ / "catalogue.yaml";
  const ReportSummary s = write_report(dir, cfg);
  const json d = embedded_data(read_text_file(s.output.string()));
  const json rows = table(d, "objects");
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0][0], "tank_0");
  EXPECT_EQ(rows[0][2], "uncertain");
  EXPECT_TRUE(rows[0][5].is_array());  // where A placed it
  EXPECT_TRUE(rows[0][6].is_null());   // B placed nothing
  EXPECT_NE(rows[0][8].get<std::string>().find("recognised in A only"), std::string::npos)
      << rows[0];
  EXPECT_NE(layer(d, "before_tank_0"), nullptr);  // the model where A placed it
  EXPECT_EQ(layer(d, "after_tank_0"), nullptr);

  // An older diff's file: the same object as "unchanged" with B's pose null.
  const std::string cj = (dir / "changes.json").string();
  json old = json::parse(read_text_file(cj));
  old["objects"][0]["status"] = "unchanged";
  for (const char* k : {"reason", "other_model", "change_area_m2", "observed_fraction"})
    old["objects"][0].erase(k);
  write_text_file(cj, old.dump());
  fs::remove(s.output);
  const json d2 = embedded_data(read_text_file(write_report(dir, config()).output.string()));
  const json rows2 = table(d2, "objects");
  ASSERT_EQ(rows2.size(), 1u);
  EXPECT_EQ(rows2[0][2], "uncertain");
  EXPECT_NE(rows2[0][8].get<std::string>().find("older file"), std::string::npos) << rows2[0];
  // An uncertain object needs at least one survey's pose; a moved one both (one clear line).
  old["objects"][0]["status"] = "uncertain";
  old["objects"][0]["T_world_model_a"] = nullptr;
  write_text_file(cj, old.dump());
  expect_error([&] { write_report(dir, config()); }, {cj, "objects[0]", "uncertain"});
}

// Colour change (sonar3d diff --colour-a/--colour-b): its regions as a table with the colours
// before and after and as rings in the 3D view; a colour out of 8-bit range is one clear error.
TEST_F(SceneReportTest, ChangesShowColourRegions) {
  const fs::path c = root_ / "colour_changes";
  fs::remove_all(c);
  fs::copy(root_ / "changes", c, fs::copy_options::recursive);
  const std::string cj = (c / "changes.json").string();
  json ch = json::parse(read_text_file(cj));
  ch["colour"] = {{"space", "chromaticity"},
                  {"regions",
                   {{{"id", 0},
                     {"centroid", {2.0, 1.5, 0.4}},
                     {"area_m2", 0.5},
                     {"max_delta", 30.1},
                     {"mean_delta", 25.2},
                     {"height_change_fraction", 0.0},
                     {"colour_a", {220, 80, 70}},
                     {"colour_b", {150, 110, 60}}}}}};
  write_text_file(cj, ch.dump());
  ReportConfig cfg = config();
  cfg.output = root_ / "colour_changes.html";
  const ReportSummary s = write_report(c, cfg);
  const json d = embedded_data(read_text_file(s.output.string()));
  EXPECT_EQ(table_rows(d, "colour_regions"), 1u);
  for (const auto& t : d["tables"]) {
    if (t["id"] != "colour_regions") continue;
    EXPECT_EQ(t["rows"][0][5], "#dc5046");  // the colour before, as hex
    EXPECT_EQ(t["rows"][0][7], 0.0);        // surface only: no height change with it
  }
  EXPECT_EQ(table_rows(d, "regions"), 2u);
  const json* ring = layer(d, "colour_regions");
  ASSERT_NE(ring, nullptr);
  EXPECT_EQ((*ring)["count"], 24);  // one circle of 24 strokes
  ch["colour"]["regions"][0]["colour_b"] = {150, 300, 60};
  write_text_file(cj, ch.dump());
  cfg.output = root_ / "colour_changes_bad.html";
  expect_error([&] { write_report(c, cfg); }, {cj, "colour.regions[0]", "colour_b", "[0, 255]"});
}

// Textured outputs of `sonar3d texture`: a cloud and a mesh in their own colours; the mesh also
// as an overlay over a map.
TEST_F(SceneReportTest, TexturedPlyInItsOwnColours) {
  const ReportSummary s = write_report(root_ / "textured_cloud.ply", config());
  EXPECT_EQ(s.input, ReportInput::Ply);
  EXPECT_EQ(s.output, root_ / "textured_cloud.html");
  const json d = embedded_data(read_text_file(s.output.string()));
  const json* c = layer(d, "cloud");
  ASSERT_NE(c, nullptr);
  EXPECT_EQ((*c)["count"], 3000);
  EXPECT_EQ((*c)["color_modes"], json({"rgb", "height"}));
  const PointCloud tc = read_ply((root_ / "textured_cloud.ply").string());
  const std::vector<unsigned char> rgb = unbase64((*c)["rgb"]);
  ASSERT_EQ(rgb.size(), 9000u);
  for (std::size_t k = 0; k < 3000; k += 7)
    for (int ch = 0; ch < 3; ++ch) EXPECT_EQ(rgb[3 * k + ch], tc.color[k][ch]);
  auto rgb_of = [&](std::size_t k) { return json{tc.color[k][0], tc.color[k][1], tc.color[k][2]}; };
  run_scene_browser_test(
      s.output,
      {{"kind", "ply"},
       {"layers", {{{"id", "cloud"}, {"type", "points"}, {"count", 3000}, {"visible", true}}}},
       {"tables", json::object()},
       {"colors",
        {{{"layer", "cloud"}, {"index", 0}, {"rgb", rgb_of(0)}},
         {{"layer", "cloud"}, {"index", 1234}, {"rgb", rgb_of(1234)}}}},
       {"mode_change", true}},
      "textured_cloud");

  // The textured mesh as a page of its own, and over the map with its placements.
  std::vector<std::vector<std::uint32_t>> faces;
  const PointCloud mv = read_ply_faces((root_ / "textured_mesh.ply").string(), &faces);
  const ReportSummary sm = write_report(root_ / "textured_mesh.ply", config());
  const json dm = embedded_data(read_text_file(sm.output.string()));
  ASSERT_EQ(dm["layers"].size(), 1u);
  EXPECT_EQ(dm["layers"][0]["type"], "mesh");
  EXPECT_EQ(dm["layers"][0]["count"].get<std::size_t>(), faces.size());
  ReportConfig cfg = config();
  cfg.placements = root_ / "placements.json";
  cfg.catalogue = root_ / "catalogue.yaml";
  cfg.overlays = {root_ / "textured_mesh.ply"};
  cfg.output = root_ / "map_overlay.html";
  const ReportSummary so = write_report(root_ / "map", cfg);
  const json dov = embedded_data(read_text_file(so.output.string()));
  ASSERT_EQ(dov["layers"].size(), 5u);
  const json* ov = layer(dov, "overlay_0");
  ASSERT_NE(ov, nullptr);
  EXPECT_EQ((*ov)["count"].get<std::size_t>(), faces.size());
  run_scene_browser_test(
      sm.output,
      {{"kind", "ply"},
       {"layers", {{{"id", "mesh"}, {"type", "mesh"}, {"count", faces.size()}, {"visible", true}}}},
       {"tables", json::object()},
       {"colors",
        {{{"layer", "mesh"},
          {"index", 3},
          {"rgb", {mv.color[3][0], mv.color[3][1], mv.color[3][2]}}}}},
       {"mode_change", false}},
      "textured_mesh");
}

// Large inputs stay within the budgets: points subsampled, meshes simplified (colours kept).
TEST_F(SceneReportTest, BudgetsBoundThePage) {
  ReportConfig cfg = config();
  cfg.max_points_per_cloud = 500;
  cfg.max_mesh_triangles = 100;
  cfg.output = root_ / "world_small.html";
  const ReportSummary s = write_report(root_ / "world", cfg);
  const json d = embedded_data(read_text_file(s.output.string()));
  for (const auto& l : d["layers"]) {
    if (l["type"] == "mesh") {
      EXPECT_LE(l["count"].get<std::size_t>(), 100u) << l["id"];
      if (!l["rgb"].is_null()) {
        EXPECT_EQ(unbase64(l["rgb"]).size(), floats(l["xyz"]).size()) << l["id"];
      }
    }
  }
  cfg.output = root_ / "changes_small.html";
  const ReportSummary sc = write_report(root_ / "changes", cfg);
  EXPECT_EQ(sc.num_cloud_points, 500u);
}

// Malformed inputs: one clear error naming the file (and the entry), and no page.
TEST_F(SceneReportTest, MalformedInputsNameTheFile) {
  const ReportConfig cfg = config();
  auto copy = [&](const std::string& from, const std::string& to) {
    const fs::path d = root_ / to;
    fs::remove_all(d);
    fs::copy(root_ / from, d, fs::copy_options::recursive);
    fs::remove(d / "report.html");
    return d;
  };
  auto fails = [&](const fs::path& in, const std::vector<std::string>& parts,
                   const ReportConfig& c) {
    expect_error([&] { write_report(in, c); }, parts);
    EXPECT_FALSE(fs::exists(in / "report.html")) << in;
  };
  const fs::path w = copy("world", "bad_world");
  const std::string graph = (w / "graph.json").string();
  write_text_file(graph, "{\"format\": \"sonar3d-world\", \"version\": 1, \"objects\": [");
  fails(w, {graph, "malformed JSON"}, cfg);
  write_text_file(graph, std::string(100000, '[') + std::string(100000, ']'));
  fails(w, {graph, "deeper than"}, cfg);
  write_text_file(graph, "{\"format\": \"sonar3d-world\", \"version\": 1e4444}");
  fails(w, {graph, "malformed JSON", "number overflow"}, cfg);  // found by fuzz_report_scene
  json g = json::parse(read_text_file((root_ / "world/graph.json").string()));
  g["objects"][0]["T_world_model"] = json::array({1, 0, 0});
  write_text_file(graph, g.dump());
  fails(w, {graph, "objects[0]", "T_world_model", "16 numbers"}, cfg);
  g = json::parse(read_text_file((root_ / "world/graph.json").string()));
  g["connections"][0]["to"] = "pillar_7";
  write_text_file(graph, g.dump());
  fails(w, {graph, "connections[0]", "pillar_7"}, cfg);
  g = json::parse(read_text_file((root_ / "world/graph.json").string()));
  g["format"] = "sonar3d-changes";
  write_text_file(graph, g.dump());
  fails(w, {graph, "format", "sonar3d-world"}, cfg);
  g = json::parse(read_text_file((root_ / "world/graph.json").string()));
  write_text_file(graph, g.dump());
  fs::remove(w / "models/sphere_0.ply");
  fails(w, {(w / "models/sphere_0.ply").string(), "not found"}, cfg);
  write_text_file((w / "models/sphere_0.ply").string(), "ply\nformat binary_little_endian 1.0\n");
  fails(w, {(w / "models/sphere_0.ply").string()}, cfg);

  const fs::path c = copy("changes", "bad_changes");
  const std::string cj = (c / "changes.json").string();
  json ch = json::parse(read_text_file(cj));
  ch["objects"][1]["status"] = "vanished";
  write_text_file(cj, ch.dump());
  fails(c, {cj, "objects[1]", "vanished"}, cfg);
  ch = json::parse(read_text_file((root_ / "changes/changes.json").string()));
  ch["objects"][0]["T_world_model_b_in_a"] = nullptr;
  write_text_file(cj, ch.dump());
  fails(c, {cj, "objects[0]", "T_world_model_b_in_a"}, cfg);
  ch = json::parse(read_text_file((root_ / "changes/changes.json").string()));
  write_text_file(cj, ch.dump());
  PointCloud no_change;
  no_change.points.emplace_back(0.f, 0.f, 0.f);
  write_ply((c / "change_points.ply").string(), no_change);
  fails(c, {(c / "change_points.ply").string(), "change_m"}, cfg);

  // Placements: malformed, a model the catalogue lacks, a catalogue that is not there.
  const fs::path bad_p = root_ / "bad_placements.json";
  ReportConfig pc = cfg;
  pc.placements = bad_p;
  pc.catalogue = root_ / "catalogue.yaml";
  pc.output = root_ / "bad_map.html";
  write_text_file(bad_p.string(), "[1, 2");
  expect_error([&] { write_report(root_ / "map", pc); }, {bad_p.string(), "not valid JSON"});
  json pj = json::parse(read_text_file((root_ / "placements.json").string()));
  pj["placements"][1]["model"] = "riser";
  write_text_file(bad_p.string(), pj.dump());
  expect_error([&] { write_report(root_ / "map", pc); },
               {bad_p.string(), "placements[1]", "'riser'", "catalogue.yaml"});
  pj = json::parse(read_text_file((root_ / "placements.json").string()));
  pj["catalogue"] = "elsewhere/none.yaml";
  write_text_file(bad_p.string(), pj.dump());
  pc.catalogue.clear();
  expect_error([&] { write_report(root_ / "map", pc); }, {"none.yaml", "--catalogue"});
  EXPECT_FALSE(fs::exists(root_ / "bad_map.html"));
  pc.catalogue = root_ / "catalogue.yaml";
  expect_error([&] { write_report(root_ / "world", pc); }, {"--placements", "world"});

  // A truncated PLY names the file.
  const fs::path trunc = root_ / "truncated.ply";
  const std::string full = read_text_file((root_ / "textured_cloud.ply").string());
  write_text_file(trunc.string(), full.substr(0, full.size() / 2));
  ReportConfig tc = cfg;
  tc.output = root_ / "truncated.html";
  expect_error([&] { write_report(trunc, tc); }, {trunc.string()});
  EXPECT_FALSE(fs::exists(root_ / "truncated.html"));

  // A file the report did not write is never replaced; its own page is.
  const fs::path mine = root_ / "mine.html";
  write_text_file(mine.string(), "<html>my notes</html>");
  ReportConfig oc = cfg;
  oc.output = mine;
  expect_error([&] { write_report(root_ / "textured_cloud.ply", oc); },
               {mine.string(), "not a page sonar3d report wrote"});
  EXPECT_EQ(read_text_file(mine.string()), "<html>my notes</html>");
  oc.output = root_ / "twice.html";
  write_report(root_ / "textured_cloud.ply", oc);
  EXPECT_NO_THROW(write_report(root_ / "textured_cloud.ply", oc));
}

// The CLI: each kind, the summary line, and one error line with a non-zero exit.
TEST_F(SceneReportTest, CommandLine) {
  const std::string cli = SONAR3D_CLI;
  if (!fs::exists(cli)) GTEST_SKIP() << "CLI not built: " << cli;
  const std::string web = " --web-dir '" + kWebDir.string() + "' -q ";
  const fs::path log = root_ / "cli.txt";
  auto run = [&](const std::string& args) {
    const int rc =
        std::system((cli + " report " + args + web + " > '" + log.string() + "' 2>&1").c_str());
    return std::make_pair(WEXITSTATUS(rc), read_text_file(log.string()));
  };
  auto [rc, out] =
      run("'" + (root_ / "map").string() + "' --placements '" +
          (root_ / "placements.json").string() + "' --catalogue '" +
          (root_ / "catalogue.yaml").string() + "' -o '" + (root_ / "cli_map.html").string() + "'");
  EXPECT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("map"), std::string::npos) << out;
  EXPECT_NE(out.find("4 layers"), std::string::npos) << out;
  // 3 placements and the per-model table's 2 rows (tank, sphere).
  EXPECT_NE(out.find("5 table rows"), std::string::npos) << out;
  std::tie(rc, out) =
      run("'" + (root_ / "world").string() + "' -o '" + (root_ / "cli_world.html").string() + "'");
  EXPECT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("5 layers"), std::string::npos) << out;
  std::tie(rc, out) = run("'" + (root_ / "catalogue.yaml").string() + "'");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("not a PLY"), std::string::npos) << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
}

}  // namespace
}  // namespace sonar3d
