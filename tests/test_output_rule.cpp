// Issue 29 item 4: one output rule for every command (core/output_dir.hpp). Every subcommand
// refuses to replace a file it did not write, replaces its own only with --overwrite, never
// writes onto or inside its own input nor onto a special file, and outputs that belong together
// (elevation's GeoTIFF + PNG, recognize's JSON + mesh, noise's mean + std, a plan's results)
// appear together or not at all — also after a kill in the middle of renaming them.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <opencv2/imgcodecs.hpp>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/io/dataset.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace sonar3d;

namespace {

using test::CliRun;

// Both streams together: a refusal must print exactly its one error line.
CliRun run_cli(const fs::path& dir, const std::string& args) {
  return test::run_cli(dir, args + " -q");
}

void write(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::trunc | std::ios::binary) << text;
}

std::string slurp(const fs::path& p) { return read_text_file(p.string()); }

// Exit status 1 and one line `sonar3d: error: ...` holding every needle.
void expect_refused(const CliRun& r, const std::vector<std::string>& needles,
                    const std::string& what) {
  EXPECT_EQ(r.code, 1) << what << ": " << r.out;
  EXPECT_EQ(r.out.rfind("sonar3d: error: ", 0), 0u) << what << ": " << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << what << ": " << r.out;
  for (const auto& n : needles)
    EXPECT_NE(r.out.find(n), std::string::npos) << what << ": " << r.out;
}

void expect_no_left_overs(const fs::path& dir) {
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string n = e.path().filename().string();
    EXPECT_EQ(n.find(".tmp-"), std::string::npos) << e.path();
    EXPECT_EQ(n.find(".backup-"), std::string::npos) << e.path();
    EXPECT_EQ(n.find(".group-"), std::string::npos) << e.path();
  }
}

// A sphere in front of a sonar moving up: 7 frames, well under a second.
const char* kScene = R"(
seed: 2
sensor: {preset: sim-10deg, beams: 40, fov_deg: 40, range_bins: 100}
simulation: {elevation_step_deg: 0.1}
objects:
  - {name: ball, primitive: {type: sphere, radius: 0.4}, pose: {translation: [2.5, 0, 0]}, reflectivity: 0.9}
trajectory: {period: 0.1, type: straight, start: [0, 0, -0.3], end: [0, 0, 0.3], spacing: 0.1}
)";

// Inputs shared by the walk: a dataset, a cloud carved from it, its elevation map.
class OutputRule : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // One folder per process: ctest runs the suite's tests in parallel processes.
    base = fs::temp_directory_path() / ("sonar3d_test_OutputRule_" + std::to_string(::getpid()));
    fs::remove_all(base);
    fs::create_directories(base);
    write(base / "scene.yaml", kScene);
    ds = base / "ds";
    cloud = base / "cloud.ply";
    map = base / "map.tif";
    ASSERT_EQ(
        run_cli(base, "simulate " + (base / "scene.yaml").string() + " -o " + ds.string()).code, 0);
    ASSERT_EQ(run_cli(base, "reconstruct " + ds.string() + " -o " + cloud.string()).code, 0);
    ASSERT_EQ(
        run_cli(base, "elevation " + cloud.string() + " --cell-m 0.02 -o " + map.string()).code, 0);
  }
  static void TearDownTestSuite() { fs::remove_all(base); }
  void SetUp() override {
    dir = test::temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  CliRun cli(const std::string& args) { return run_cli(dir, args); }
  static fs::path base, ds, cloud, map;
  fs::path dir;
};
fs::path OutputRule::base, OutputRule::ds, OutputRule::cloud, OutputRule::map;

// One subcommand writing one file: `args(OUT)` is its command line, `input` a file it reads.
struct Writer {
  std::string name;
  std::string ext;
  std::function<std::string(const fs::path&)> args;
  fs::path input;
  bool reads_dataset = false;  // then a path inside the dataset is refused as well
};

}  // namespace

TEST_F(OutputRule, EverySubcommandFollowsTheRule) {
  const std::vector<Writer> writers = {
      {"reconstruct -o", ".ply",
       [&](const fs::path& o) { return "reconstruct " + ds.string() + " -o " + o.string(); },
       ds / "frames.csv", true},
      {"reconstruct --json", ".json",
       [&](const fs::path& o) {
         return "reconstruct " + ds.string() + " -o " +
                (dir / (o.filename().string() + ".ply")).string() + " --json " + o.string();
       },
       ds / "sonar.yaml", true},
      {"preview -o", ".png",
       [&](const fs::path& o) { return "preview " + ds.string() + " -o " + o.string(); },
       ds / "frames" / "000000.png", true},
      {"elevation -o", ".tif",
       [&](const fs::path& o) {
         return "elevation " + cloud.string() + " --cell-m 0.02 -o " + o.string();
       },
       cloud},
      {"evaluate --json", ".json",
       [&](const fs::path& o) {
         return "evaluate " + cloud.string() + " --truth " + ds.string() + " --json " + o.string();
       },
       cloud, true},
      {"register --json", ".json",
       [&](const fs::path& o) {
         return "register " + map.string() + " " + map.string() +
                " --search 0.1 --min-overlap-cells 10 --json " + o.string();
       },
       map},
  };
  for (std::size_t i = 0; i < writers.size(); ++i) {
    const Writer& w = writers[i];
    SCOPED_TRACE(w.name);
    dir = test::temp_dir("writer" + std::to_string(i));  // a fresh directory for each
    // A file sonar3d did not write: an error naming it, with or without --overwrite; untouched.
    const fs::path foreign = dir / ("foreign" + w.ext);
    write(foreign, "precious\n");
    for (const char* extra : {"", " --overwrite"}) {
      expect_refused(cli(w.args(foreign) + extra), {"'" + foreign.string() + "'", "not a sonar3d"},
                     w.name + " onto a foreign file");
      EXPECT_EQ(slurp(foreign), "precious\n");
    }
    // Its own output: replaced only with --overwrite.
    const fs::path own = dir / ("own" + w.ext);
    const CliRun first = cli(w.args(own));
    ASSERT_EQ(first.code, 0) << first.out;
    ASSERT_TRUE(fs::is_regular_file(own));
    expect_refused(cli(w.args(own)), {"already holds a sonar3d", "--overwrite"},
                   w.name + " onto its own output");
    const CliRun again = cli(w.args(own) + " --overwrite");
    EXPECT_EQ(again.code, 0) << again.out;
    // Its own input, and a path inside the input dataset: refused, the input unchanged.
    const std::string before = slurp(w.input);
    for (const char* extra : {"", " --overwrite"}) {
      expect_refused(cli(w.args(w.input) + extra), {"'" + w.input.string() + "'", "input"},
                     w.name + " onto its input");
      EXPECT_EQ(slurp(w.input), before);
    }
    if (w.reads_dataset) {
      const fs::path inside = ds / ("new" + w.ext);
      expect_refused(cli(w.args(inside)), {"lies inside the input"}, w.name + " into its dataset");
      EXPECT_FALSE(fs::exists(inside));
    }
    // A FIFO (a reader waiting on it would otherwise get a regular file in its place).
    const fs::path fifo = dir / ("fifo" + w.ext);
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    expect_refused(cli(w.args(fifo) + " --overwrite"), {"'" + fifo.string() + "'", "FIFO"},
                   w.name + " onto a FIFO");
    EXPECT_TRUE(fs::is_fifo(fifo));
    fs::remove(fifo);
    expect_no_left_overs(dir);
  }
  // A device: never replaced, not even with --overwrite.
  expect_refused(cli("evaluate " + cloud.string() + " --truth " + ds.string() +
                     " --json /dev/null --overwrite"),
                 {"'/dev/null'", "character device"}, "evaluate --json /dev/null");
}

TEST_F(OutputRule, ElevationMapAndItsPictureAppearTogether) {
  const fs::path tif = dir / "m.tif", png = dir / "m.png";
  write(png, "not a picture\n");  // a foreign file at --png: neither is written
  expect_refused(cli("elevation " + cloud.string() + " -o " + tif.string() + " --png " +
                     png.string() + " --overwrite"),
                 {"'" + png.string() + "'"}, "elevation --png onto a foreign file");
  EXPECT_FALSE(fs::exists(tif));
  EXPECT_EQ(slurp(png), "not a picture\n");
  fs::remove(png);
  ASSERT_EQ(
      cli("elevation " + cloud.string() + " -o " + tif.string() + " --png " + png.string()).code,
      0);
  EXPECT_TRUE(is_sonar3d_output(tif, OutputKind::GeoTiff));
  EXPECT_TRUE(is_sonar3d_output(png, OutputKind::Png));
  EXPECT_FALSE(cv::imread(png.string()).empty());  // the marked PNG still decodes
  // -o and --png the same file.
  expect_refused(cli("elevation " + cloud.string() + " -o " + tif.string() + " --png " +
                     tif.string() + " --overwrite"),
                 {"name the same file"}, "elevation -o X --png X");
  expect_no_left_overs(dir);
}

TEST_F(OutputRule, NoiseEstimateAndPlanRefuseWhatTheyDidNotWrite) {
  // noise estimate: foreign mean.tiff is never replaced, not even with --overwrite.
  const fs::path noise = dir / "noise";
  fs::create_directories(noise);
  write(noise / "mean.tiff", "foreign\n");
  expect_refused(cli("noise estimate " + ds.string() + " -o " + noise.string() + " --overwrite"),
                 {"mean.tiff", "not a sonar3d TIFF image"}, "noise onto foreign mean.tiff");
  EXPECT_EQ(slurp(noise / "mean.tiff"), "foreign\n");
  EXPECT_FALSE(fs::exists(noise / "std.tiff"));
  fs::remove(noise / "mean.tiff");
  ASSERT_EQ(cli("noise estimate " + ds.string() + " -o " + noise.string()).code, 0);
  EXPECT_TRUE(is_sonar3d_output(noise / "mean.tiff", OutputKind::Tiff));
  EXPECT_TRUE(is_sonar3d_output(noise / "std.tiff", OutputKind::Tiff));
  expect_refused(cli("noise estimate " + ds.string() + " -o " + noise.string()), {"--overwrite"},
                 "noise onto its own");
  EXPECT_EQ(cli("noise estimate " + ds.string() + " -o " + noise.string() + " --overwrite").code,
            0);
  expect_refused(cli("noise estimate " + ds.string() + " -o " + (ds / "noise2").string()),
                 {"lies inside the input"}, "noise into its dataset");
  EXPECT_FALSE(fs::exists(ds / "noise2"));
  // plan: a foreign non-empty directory, a FIFO, the sweep file itself.
  const fs::path sweep = dir / "sweep.yaml";
  write(sweep, "not read\n");
  const fs::path foreign = dir / "foreign_dir";
  fs::create_directories(foreign);
  write(foreign / "results.csv", "mine\n");
  expect_refused(cli("plan " + sweep.string() + " -o " + foreign.string()),
                 {"'" + foreign.string() + "'", "not a sonar3d plan directory"},
                 "plan into a foreign dir");
  EXPECT_EQ(slurp(foreign / "results.csv"), "mine\n");
  EXPECT_FALSE(fs::exists(foreign / "points"));
  const fs::path fifo = dir / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  expect_refused(cli("plan " + sweep.string() + " -o " + fifo.string()), {"FIFO"}, "plan -o FIFO");
  expect_refused(cli("plan " + sweep.string() + " -o " + sweep.string()), {"is the input"},
                 "plan -o its sweep");
  EXPECT_EQ(slurp(sweep), "not read\n");
}

// ---------------------------------------------------------------- the library helper

TEST(OutputRuleLibrary, KindsAreRecognisedByTheirMarks) {
  const fs::path dir = test::temp_dir("marks");
  // TIFF: sonar3d's float images carry the Software tag, and still read back the same.
  SonarImage im(5, 7);
  for (std::size_t i = 0; i < im.data.size(); ++i) im.data[i] = 0.25f * static_cast<float>(i);
  write_float_image((dir / "a.tiff").string(), im);
  EXPECT_TRUE(is_sonar3d_output(dir / "a.tiff", OutputKind::Tiff));
  const cv::Mat back = cv::imread((dir / "a.tiff").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(back.type(), CV_32F);
  ASSERT_EQ(back.rows, 5);
  EXPECT_FLOAT_EQ(back.at<float>(4, 6), 0.25f * 34);
  cv::Mat plain(4, 4, CV_32F, cv::Scalar(1.0f));
  cv::imwrite((dir / "b.tiff").string(), plain);
  EXPECT_FALSE(is_sonar3d_output(dir / "b.tiff", OutputKind::Tiff));
  mark_tiff_as_sonar3d(dir / "b.tiff");
  EXPECT_TRUE(is_sonar3d_output(dir / "b.tiff", OutputKind::Tiff));
  EXPECT_EQ(cv::imread((dir / "b.tiff").string(), cv::IMREAD_UNCHANGED).at<float>(3, 3), 1.0f);
  // PNG: a tEXt chunk.
  cv::Mat pic(3, 3, CV_8UC3, cv::Scalar(1, 2, 3));
  cv::imwrite((dir / "p.png").string(), pic);
  EXPECT_FALSE(is_sonar3d_output(dir / "p.png", OutputKind::Png));
  mark_png_as_sonar3d(dir / "p.png");
  EXPECT_TRUE(is_sonar3d_output(dir / "p.png", OutputKind::Png));
  EXPECT_EQ(cv::imread((dir / "p.png").string()).at<cv::Vec3b>(2, 2), cv::Vec3b(1, 2, 3));
  test::expect_error([&] { mark_png_as_sonar3d(dir / "a.tiff"); }, "not a PNG");
  // PLY and JSON; a kind is not another kind.
  PointCloud c;
  c.points.push_back(Eigen::Vector3f(1, 2, 3));
  write_ply((dir / "c.ply").string(), c);
  EXPECT_TRUE(is_sonar3d_output(dir / "c.ply", OutputKind::PointCloud));
  EXPECT_FALSE(is_sonar3d_output(dir / "c.ply", OutputKind::Mesh));
  // A writer that sorts its keys puts "format" after a long "candidates" list (a 3D recognition's
  // placements): still its own file.
  write(dir / "p3d.json", "{\"candidates\": [\"" + std::string(10000, 'x') +
                              "\"], \"format\": \"sonar3d-placements\", \"version\": 1}");
  EXPECT_TRUE(is_sonar3d_output(dir / "p3d.json", OutputKind::PlacementsJson));
  write(dir / "other.json", "{\"candidates\": [\"" + std::string(10000, 'x') + "\"]}");
  EXPECT_FALSE(is_sonar3d_output(dir / "other.json", OutputKind::PlacementsJson));
  write(dir / "e.json", "[{\"format\": \"sonar3d-evaluation\"}]");
  EXPECT_TRUE(is_sonar3d_output(dir / "e.json", OutputKind::EvaluationJson));
  EXPECT_FALSE(is_sonar3d_output(dir / "e.json", OutputKind::RegistrationJson));
  OutputPolicy policy;
  policy.overwrite = true;
  test::expect_error([&] { check_output(dir / "e.json", OutputKind::PlacementsJson, policy); },
                     "is a sonar3d evaluation, not a placements file");
  test::expect_error([&] { check_output(dir, OutputKind::PointCloud, policy, "--x"); },
                     "(--x) is a directory");
  test::expect_error([&] { check_output(dir / "no" / "c.ply", OutputKind::PointCloud, policy); },
                     "does not exist");
}

namespace {

// Runs `body` in a child process killed (SIGKILL) by `after_rename(i)` at `kill_at`; waits.
void commit_killed_at(const fs::path& a, const fs::path& b, std::size_t kill_at) {
  const pid_t pid = fork();
  if (pid == 0) {
    OutputFiles out(OutputPolicy{true, {}, {}});
    write(out.add(a, OutputKind::EvaluationJson), "{\"format\": \"sonar3d-evaluation\", \"v\": 2}");
    write(out.add(b, OutputKind::RegistrationJson),
          "{\"format\": \"sonar3d-registration\", \"v\": 2}");
    out.commit([&](std::size_t i) {
      if (i == kill_at) ::kill(::getpid(), SIGKILL);
    });
    _exit(0);
  }
  int st = 0;
  ASSERT_EQ(waitpid(pid, &st, 0), pid);
  ASSERT_TRUE(WIFSIGNALED(st) && WTERMSIG(st) == SIGKILL);
}

}  // namespace

TEST(OutputRuleLibrary, APairKilledWhileRenamedAppearsWholeOrNotAtAll) {
  const fs::path dir = test::temp_dir("kill");
  const fs::path a = dir / "a.json", b = dir / "b.json";
  const std::string a1 = "{\"format\": \"sonar3d-evaluation\", \"v\": 1}",
                    b1 = "{\"format\": \"sonar3d-registration\", \"v\": 1}";
  // No previous version; killed after the first rename: the next run removes the lone file.
  commit_killed_at(a, b, 0);
  EXPECT_TRUE(fs::exists(a));
  EXPECT_FALSE(fs::exists(b));
  const std::vector<std::string> notes = recover_interrupted_writes(b);
  ASSERT_FALSE(notes.empty());
  EXPECT_NE(notes[0].find("rolled back"), std::string::npos) << notes[0];
  EXPECT_FALSE(fs::exists(a));
  EXPECT_FALSE(fs::exists(b));
  expect_no_left_overs(dir);
  // Previous versions: killed after the first rename, both previous versions come back.
  write(a, a1);
  write(b, b1);
  commit_killed_at(a, b, 0);
  OutputFiles next(OutputPolicy{true, {}, {}});
  next.add(a, OutputKind::EvaluationJson);  // any member's next writer recovers the set
  EXPECT_EQ(slurp(a), a1);
  EXPECT_EQ(slurp(b), b1);
  // Killed after the last rename: the new set is complete and kept.
  commit_killed_at(a, b, 1);
  EXPECT_FALSE(recover_interrupted_writes(a).empty());
  EXPECT_NE(slurp(a).find("\"v\": 2"), std::string::npos);
  EXPECT_NE(slurp(b).find("\"v\": 2"), std::string::npos);
  expect_no_left_overs(dir);
  // A failed write: nothing appears, the previous versions stay.
  {
    OutputFiles out(OutputPolicy{true, {}, {}});
    write(out.add(a, OutputKind::EvaluationJson), "{\"format\": \"sonar3d-evaluation\"}");
    out.add(b, OutputKind::RegistrationJson);  // never written
    test::expect_error([&] { out.commit(); }, "was not written");
  }
  EXPECT_NE(slurp(a).find("\"v\": 2"), std::string::npos);
  expect_no_left_overs(dir);
}
