// `sonar3d report`: the page written for a fixture plan directory (a 2 objects × 3 apertures ×
// 3 spacings × 2 methods sweep with one failed point, clouds sampled on the CAD surfaces with
// aperture-dependent noise) is self-contained, embeds the data and the per-point errors
// exactly, subsamples and simplifies as configured, fails clearly on bad input, and renders in
// headless Chromium (web/test_report.mjs).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
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

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/report/report.hpp"
#include "sonar3d/sim/reference_objects.hpp"

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
  static ReportConfig config() {
    ReportConfig cfg;
    cfg.web_dir = kWebDir;
    return cfg;
  }
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
  expect_error([&] { write_report(root_ / "plan", zero); }, {"max_points_per_cloud"});
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

}  // namespace
}  // namespace sonar3d
