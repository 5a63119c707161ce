// Never destroy what sonar3d did not write, never report an empty result as a success, and keep
// the command line's promises (one error line, documented exit statuses, a stoppable planner).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "../src/plan/plan_internal.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/plan/sweep.hpp"
#include "test_support.hpp"

extern char** environ;
namespace fs = std::filesystem;
using sonar3d::read_text_file;

namespace {

struct CliRun {
  int code;
  std::string out, err;
};

// Runs the CLI with `args` (a shell command line) in `dir`'s context; captures both streams.
CliRun run(const fs::path& dir, const std::string& args) {
  const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string cmd =
      std::string(SONAR3D_CLI) + " " + args + " > " + out.string() + " 2> " + err.string();
  const int status = std::system(cmd.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, read_text_file(out.string()),
          read_text_file(err.string())};
}

void write(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::trunc) << text;
}

std::size_t lines(const std::string& s) { return std::count(s.begin(), s.end(), '\n'); }

// One line `sonar3d: error: ...` naming `needle`, status `code`.
void expect_error(const CliRun& r, int code, const std::string& needle) {
  EXPECT_EQ(r.code, code) << r.err;
  EXPECT_EQ(r.err.rfind("sonar3d: error: ", 0), 0u) << r.err;
  EXPECT_EQ(lines(r.err), 1u) << r.err;
  EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
}

// Nothing sonar3d-temporary is left in `dir`.
void expect_no_left_overs(const fs::path& dir) {
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string n = e.path().filename().string();
    EXPECT_EQ(n.find(".tmp-"), std::string::npos) << e.path();
    EXPECT_EQ(n.find(".backup-"), std::string::npos) << e.path();
  }
}

// A pid that no process has: a child that exited and was reaped.
pid_t dead_pid() {
  const pid_t pid = fork();
  if (pid == 0) _exit(0);
  int st = 0;
  waitpid(pid, &st, 0);
  return pid;
}

// A sphere in front of a sonar moving up: 7 frames, well under a second.
const char* kScene = R"(
seed: 2
sensor: {preset: sim-10deg, beams: 40, fov_deg: 40, range_bins: 100}
simulation: {elevation_step_deg: 0.1}
objects:
  - {name: ball, primitive: {type: sphere, radius: 0.4}, pose: {translation: [X, 0, 0]}, reflectivity: 0.9}
trajectory: {period: 0.1, type: straight, start: [0, 0, -0.3], end: [0, 0, 0.3], spacing: 0.1}
)";

std::string scene_at(double x) {
  std::string s = kScene;
  s.replace(s.find('X'), 1, std::to_string(x));
  return s;
}

class Safety : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = sonar3d::test::temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    write(dir / "scene.yaml", scene_at(2.5));
    write(dir / "behind.yaml", scene_at(-2.5));  // the sonar looks along +x: never in view
  }
  CliRun cli(const std::string& args) { return run(dir, args); }
  std::string simulate(const std::string& scene, const fs::path& out,
                       const std::string& extra = "") {
    return "simulate " + (dir / scene).string() + " -o " + out.string() + " -q " + extra;
  }
  fs::path dir;
};

}  // namespace

// ---------------------------------------------------------------- item 5: outputs

TEST_F(Safety, SimulateNeverReplacesWhatItDidNotWrite) {
  // A directory of someone else's data: refused, named, untouched (even with --overwrite).
  const fs::path mine = dir / "mine";
  fs::create_directories(mine);
  write(mine / "notes.txt", "precious");
  for (const char* extra : {"", "--overwrite"}) {
    expect_error(cli(simulate("scene.yaml", mine, extra)), 1, "'" + mine.string() + "'");
    EXPECT_EQ(read_text_file((mine / "notes.txt").string()), "precious");
  }
  // A file: refused.
  write(dir / "file", "data");
  expect_error(cli(simulate("scene.yaml", dir / "file", "--overwrite")), 1, "not a directory");
  EXPECT_EQ(read_text_file((dir / "file").string()), "data");
  // The scene file itself as the output: refused.
  expect_error(cli(simulate("scene.yaml", dir / "scene.yaml", "--overwrite")), 1, "is the input");

  // An empty directory is written; a sonar3d dataset is replaced only with --overwrite.
  const fs::path ds = dir / "ds";
  fs::create_directories(ds);
  ASSERT_EQ(cli(simulate("scene.yaml", ds)).code, 0);
  EXPECT_TRUE(fs::exists(ds / "sonar.yaml"));
  const CliRun again = cli(simulate("scene.yaml", ds));
  expect_error(again, 1, "--overwrite");
  write(ds / "marker", "old");
  ASSERT_EQ(cli(simulate("scene.yaml", ds, "--overwrite")).code, 0);
  EXPECT_FALSE(fs::exists(ds / "marker"));  // replaced as a whole
  EXPECT_EQ(sonar3d::read_dataset(ds).size(), 7u);
  expect_no_left_overs(dir);
}

TEST_F(Safety, ImportSourceIsNeverTheDestination) {
  // Inputs for `import frames` taken from a simulated dataset.
  const fs::path ds = dir / "ds";
  ASSERT_EQ(cli(simulate("scene.yaml", ds)).code, 0);
  const sonar3d::Dataset d = sonar3d::read_dataset(ds);
  std::ostringstream times;
  times << "timestamp,file\n";
  for (const auto& f : d.frames)
    times << f.timestamp << "," << fs::path(f.file).filename().string() << "\n";
  write(dir / "times.csv", times.str());
  write(dir / "sonar.yaml", sonar3d::sonar_spec_to_yaml(d.spec));
  fs::copy(ds / "frames", dir / "images");
  fs::copy(ds / "navigation.tum", dir / "nav.tum");
  auto import = [&](const fs::path& images, const fs::path& out, const std::string& extra) {
    return cli("import frames --images " + images.string() + " --times " +
               (dir / "times.csv").string() + " --nav " + (dir / "nav.tum").string() + " --sonar " +
               (dir / "sonar.yaml").string() + " -o " + out.string() + " -q " + extra);
  };
  const std::size_t n_images = d.size();
  auto count = [](const fs::path& p) {
    return static_cast<std::size_t>(std::distance(fs::directory_iterator(p), {}));
  };
  // The output is the recording, lies inside it, or contains it (its frames would be deleted).
  expect_error(import(dir / "images", dir / "images", "--overwrite"), 1, "is the input");
  expect_error(import(dir / "images", dir / "images/out", "--overwrite"), 1,
               "lies inside the input");
  expect_error(import(dir / "images/.", dir / "images/../images", ""), 1, "is the input");
  EXPECT_EQ(count(dir / "images"), n_images);
  expect_error(import(ds / "frames", ds, "--overwrite"), 1, "lies inside the output");
  EXPECT_EQ(count(ds / "frames"), n_images);
  // Elsewhere, it works (and the check does not get in the way).
  const CliRun ok = import(dir / "images", dir / "imported", "");
  ASSERT_EQ(ok.code, 0) << ok.err;
  EXPECT_EQ(sonar3d::read_dataset(dir / "imported").size(), n_images);
}

TEST_F(Safety, InterruptedReplacementIsRestoredAndStaleTemporariesRemoved) {
  const fs::path ds = dir / "ds";
  ASSERT_EQ(cli(simulate("scene.yaml", ds)).code, 0);
  // A crash between the two renames of a replacement: the old dataset sits under its backup name
  // and nothing is at the destination. The next run restores it (and says so) before deciding.
  const pid_t dead = dead_pid();
  const fs::path backup = dir / (".ds.backup-" + std::to_string(dead) + "-0");
  fs::rename(ds, backup);
  const fs::path stale = dir / (".ds.tmp-" + std::to_string(dead) + "-1");
  const fs::path nested = dir / ("..ds.tmp-" + std::to_string(dead) + "-1.tmp-7-0");
  const fs::path live = dir / (".ds.tmp-" + std::to_string(getppid()) + "-1");
  for (const auto& p : {stale, nested, live}) fs::create_directories(p / "frames");
  const CliRun r = cli(simulate("scene.yaml", ds));
  EXPECT_NE(r.err.find("sonar3d: note: restored '" + ds.string() + "'"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("already holds a sonar3d dataset"), std::string::npos) << r.err;
  EXPECT_EQ(r.code, 1);
  EXPECT_EQ(sonar3d::read_dataset(ds).size(), 7u);
  EXPECT_FALSE(fs::exists(backup));
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_FALSE(fs::exists(nested));
  EXPECT_TRUE(fs::exists(live));  // a running process' temporary is not ours to remove
  fs::remove_all(live);

  // A crash after the renames: the backup is of a replaced version, and goes.
  fs::create_directories(backup);
  const auto notes = sonar3d::recover_interrupted_writes(ds);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("removed"), std::string::npos) << notes[0];
  EXPECT_FALSE(fs::exists(backup));
  EXPECT_TRUE(fs::exists(ds / "sonar.yaml"));

  // A directory replacement through AtomicPath (the library's DatasetWriter, the Python module)
  // leaves no backup behind, and never replaces a directory that is not a sonar3d dataset.
  auto replace = [&](const std::string& file) {
    sonar3d::AtomicPath p(dir / "d");
    fs::create_directories(p.temp());
    write(p.temp() / "sonar.yaml", "format: sonar3d-dataset\nversion: 1\n");
    write(p.temp() / file, "1");
    p.commit();
  };
  replace("a");
  replace("b");
  EXPECT_FALSE(fs::exists(dir / "d/a"));
  EXPECT_TRUE(fs::exists(dir / "d/b"));
  fs::create_directories(dir / "user");
  write(dir / "user/keep", "mine");
  sonar3d::test::expect_error(
      [&] {
        sonar3d::AtomicPath p(dir / "user");
        fs::create_directories(p.temp());
        write(p.temp() / "sonar.yaml", "format: sonar3d-dataset\nversion: 1\n");
        p.commit();
      },
      "is not a sonar3d output of the same kind");
  EXPECT_EQ(read_text_file((dir / "user/keep").string()), "mine");
  expect_no_left_overs(dir);
}

TEST_F(Safety, NoiseEstimateNeverLeavesMeanWithoutStd) {
  const fs::path ds = dir / "ds";
  ASSERT_EQ(cli(simulate("scene.yaml", ds)).code, 0);
  const fs::path out = dir / "noise";
  // std.tiff cannot be written (a directory holds its name): mean.tiff must not appear alone.
  fs::create_directories(out / "std.tiff/x");
  for (const char* extra : {"", "--overwrite"}) {
    const CliRun r = cli("noise estimate " + ds.string() + " -o " + out.string() + " -q " + extra);
    EXPECT_EQ(r.code, 1) << r.err;
    EXPECT_NE(r.err.find("std.tiff"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out / "mean.tiff"));
  }
  fs::remove_all(out / "std.tiff");
  ASSERT_EQ(cli("noise estimate " + ds.string() + " -o " + out.string() + " -q").code, 0);
  EXPECT_TRUE(fs::exists(out / "mean.tiff"));
  EXPECT_TRUE(fs::exists(out / "std.tiff"));
  // Existing statistics are replaced only with --overwrite.
  expect_error(cli("noise estimate " + ds.string() + " -o " + out.string() + " -q"), 1,
               "--overwrite");
  EXPECT_EQ(cli("noise estimate " + ds.string() + " -o " + out.string() + " -q --overwrite").code,
            0);
  expect_no_left_overs(out);
}

TEST_F(Safety, OutputsAreFlushedBeforeTheyAreRenamed) {
  // The system calls of a simulation, in order (strace is a development tool: skipped without it).
  const fs::path trace = dir / "trace.txt";
  const std::string cmd = "strace -f -qq -e trace=fsync,syncfs,rename,renameat,renameat2 -o " +
                          trace.string() + " " + SONAR3D_CLI + " " +
                          simulate("scene.yaml", dir / "ds") + " > /dev/null 2>&1";
  if (std::system(("command -v strace > /dev/null && " + cmd).c_str()) != 0 ||
      !fs::exists(dir / "ds")) {
    GTEST_SKIP() << "strace is not available (or may not trace here)";
  }
  std::vector<std::string> calls;
  std::istringstream in(read_text_file(trace.string()));
  for (std::string line; std::getline(in, line);) {
    for (const char* c : {"fsync(", "syncfs(", "rename"}) {
      if (line.find(c) != std::string::npos) calls.push_back(c);
    }
  }
  // Every rename (sonar.yaml, frames.csv, truth/*, the dataset directory) is preceded by a flush of
  // what it renames and followed by a flush of the directory it renamed into.
  std::size_t renames = 0;
  for (std::size_t i = 0; i < calls.size(); ++i) {
    if (calls[i] != "rename") continue;
    ++renames;
    EXPECT_TRUE(i > 0 && calls[i - 1] != "rename") << "rename #" << renames << " not flushed";
    EXPECT_TRUE(i + 1 < calls.size() && calls[i + 1] == "fsync(")
        << "directory not flushed after rename #" << renames;
  }
  EXPECT_GE(renames, 5u);
  EXPECT_NE(std::find(calls.begin(), calls.end(), "syncfs("), calls.end());
}

// ---------------------------------------------------------------- item 6: empty results

TEST_F(Safety, NothingInViewIsAnErrorUnlessAllowed) {
  const fs::path ds = dir / "ds";
  expect_error(cli(simulate("behind.yaml", ds)), 1, "no object is in view");
  EXPECT_FALSE(fs::exists(ds));
  expect_no_left_overs(dir);
  ASSERT_EQ(cli(simulate("behind.yaml", ds, "--allow-empty")).code, 0);

  // Reconstructions of it: 0 points is an error saying why, and no cloud is written.
  const fs::path ply = dir / "cloud.ply";
  expect_error(cli("reconstruct " + ds.string() + " --method carve -q -o " + ply.string()), 1,
               "carving found no surface");
  expect_error(cli("reconstruct " + ds.string() + " --method deconv --deconv-mode passes -q -o " +
                   ply.string()),
               1, "no return in any frame");
  EXPECT_FALSE(fs::exists(ply));
  // The default mode (auto) tries the voxel mode too, says so in a note, then fails the same way.
  const CliRun deconv_auto =
      cli("reconstruct " + ds.string() + " --method deconv -q -o " + ply.string());
  EXPECT_EQ(deconv_auto.code, 1) << deconv_auto.err;
  EXPECT_NE(deconv_auto.err.find("sonar3d: error: deconvolution produced 0 points"),
            std::string::npos)
      << deconv_auto.err;
  EXPECT_FALSE(fs::exists(ply));
  const CliRun allowed =
      cli("reconstruct " + ds.string() + " --method carve -q --allow-empty -o " + ply.string());
  EXPECT_EQ(allowed.code, 0) << allowed.err;
  EXPECT_TRUE(fs::exists(ply));
}

TEST_F(Safety, DeconvolutionOfAnOrbitFailsWithOneSummary) {
  write(dir / "orbit.yaml",
        "seed: 2\nsensor: {preset: sim-10deg, beams: 40, fov_deg: 40, range_bins: 100}\n"
        "simulation: {elevation_step_deg: 0.1}\nobjects:\n"
        "  - {name: ball, primitive: {type: sphere, radius: 0.4}, reflectivity: 0.9}\n"
        "trajectory: {period: 0.1, type: orbit, center: [0, 0, 0], radius: 2.5, count: 60, "
        "start_deg: 180, sweep_deg: 360}\n");
  const fs::path ds = dir / "orbit";
  ASSERT_EQ(cli(simulate("orbit.yaml", ds)).code, 0);
  const CliRun r = cli("reconstruct " + ds.string() +
                       " --method deconv --deconv-mode passes -q -o " + (dir / "o.ply").string());
  expect_error(r, 1, "deconvolution reconstructed no pass of the 60 frames");
  EXPECT_NE(r.err.find("--method carve"), std::string::npos) << r.err;
  // 60 skipped passes: one summary in the error line (warnings never on stdout), not 60 warnings.
  EXPECT_EQ(r.out.find("warning"), std::string::npos) << r.out;
  EXPECT_NE(r.err.find("60 passes"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "o.ply"));
  // The default mode, auto (issue 29), deconvolves the orbit in the voxel mode and says so in
  // one line on stderr.
  const CliRun a =
      cli("reconstruct " + ds.string() + " --method deconv -q -o " + (dir / "o.ply").string());
  EXPECT_EQ(a.code, 0) << a.err;
  EXPECT_EQ(a.err.rfind("sonar3d: note: deconvolution mode auto: voxel mode", 0), 0u) << a.err;
  EXPECT_NE(a.err.find("60 of 60 frames lie in no pass"), std::string::npos) << a.err;
  // The other lines of stderr are warnings naming flags (issue 29: warnings never on stdout).
  EXPECT_EQ(a.err.find("\n", a.err.find("\n") + 1) == std::string::npos ||
                a.err.find("\nsonar3d: warning: ") != std::string::npos,
            true)
      << a.err;
  EXPECT_EQ(a.err.find("deconv.voxel."), std::string::npos) << a.err;
  EXPECT_EQ(a.out.find("deconvolution mode auto"), std::string::npos) << a.out;  // not stdout
  EXPECT_EQ(a.out.find("warning"), std::string::npos) << a.out;
  EXPECT_TRUE(sonar3d::is_sonar3d_ply((dir / "o.ply").string()));
}

TEST(PlanSafety, AWorkerThatDiedFailsItsPointWhateverItWrote) {
  const fs::path dir = sonar3d::test::temp_dir("died");
  write(dir / "s.yaml",
        "seed: 3\nworkers: 1\naxes: {spacing_m: [0.05, 0.1]}\n"
        "fixed: {aperture_deg: 10, fov_deg: 30, bearing_res_deg: 0.5, range_res_m: 0.04, "
        "voxel_m: 0.04, standoff_m: 2}\n");
  const sonar3d::Sweep sweep = sonar3d::load_sweep((dir / "s.yaml").string());
  const fs::path out = dir / "out";
  // A worker that writes an "ok" status with good metrics, then crashes (as one could in its
  // exit path), for point 0; point 1's worker exits 0 with its ok status.
  for (std::size_t i = 0; i < sweep.size(); ++i) {
    nlohmann::json st = {{"id", sonar3d::point_id(i)},
                         {"index", i},
                         {"params_key", sonar3d::plan_params_key(sweep.point(i))},
                         {"status", "ok"},
                         {"metrics", {{"median_to_coverage", 0.1 + i}}}};
    fs::create_directories(out / "points" / sonar3d::point_id(i));
    write(out / "points" / sonar3d::point_id(i) / "next.json", st.dump());
  }
  write(dir / "worker.sh",
        "#!/bin/sh\nd=\"$2/points/$(printf 'p%04d' \"$3\")\"\ncp \"$d/next.json\" "
        "\"$d/status.json\"\n"
        "if [ \"$3\" = 0 ]; then kill -SEGV $$; fi\nexit 0\n");
  fs::permissions(dir / "worker.sh", fs::perms::owner_all);
  sonar3d::PlanOptions opt;
  opt.out_dir = out;
  opt.worker_executable = (dir / "worker.sh").string();
  opt.progress = false;
  const sonar3d::PlanSummary s = sonar3d::run_sweep(sweep, opt);
  EXPECT_EQ(s.failed, 1u);
  EXPECT_EQ(sonar3d::write_sweep_results(sweep, out), 1u);
  const auto results = nlohmann::json::parse(read_text_file((out / "results.json").string()));
  const auto& p0 = results["points"][0];
  EXPECT_EQ(p0["status"], "failed") << p0.dump();
  EXPECT_NE(p0["message"].get<std::string>().find("signal 11"), std::string::npos) << p0.dump();
  EXPECT_TRUE(p0["rank"].is_null());
  EXPECT_EQ(results["points"][1]["rank"], 1);
}

TEST(PlanSafety, NoSucceededPointIsAnErrorUnlessAllowed) {
  const fs::path dir = sonar3d::test::temp_dir("none");
  write(dir / "s.yaml",
        "seed: 3\nworkers: 1\naxes: {object: [nowhere.stl]}\n"
        "fixed: {aperture_deg: 10, fov_deg: 30, bearing_res_deg: 0.5, range_res_m: 0.04, "
        "voxel_m: 0.04, standoff_m: 2}\n");
  const std::string plan =
      "plan " + (dir / "s.yaml").string() + " -o " + (dir / "out").string() + " -q";
  const CliRun r = run(dir, plan);
  expect_error(r, 1, "no point of the sweep succeeded");
  EXPECT_NE(r.out.find("1 failed"), std::string::npos) << r.out;
  EXPECT_EQ(run(dir, plan + " --allow-empty").code, 0);
}

// ---------------------------------------------------------------- item 7: CLI promises

TEST_F(Safety, UsageErrorsExit2WithOneLine) {
  expect_error(cli("simulate --no-such-flag " + (dir / "scene.yaml").string() + " -o x"), 2,
               "--no-such-flag");
  expect_error(cli("reconstruct"), 2, "sonar3d reconstruct --help");
  expect_error(cli("frobnicate"), 2, "sonar3d: error:");
  expect_error(cli("reconstruct " + (dir / "missing").string() + " -o x.ply"), 2, "missing");
  expect_error(cli("reconstruct " + dir.string() + " -o x.ply --method magic"), 2, "magic");
  // Failures of the work itself: status 1.
  expect_error(cli("info " + dir.string()), 1, "sonar.yaml is missing");
  const CliRun help = cli("--help");
  EXPECT_EQ(help.code, 0);
  EXPECT_NE(help.out.find("2 usage error"), std::string::npos);
}

namespace {

// Pids of the planner workers writing into `out` (from /proc/*/cmdline).
std::vector<pid_t> plan_workers(const fs::path& out) {
  std::vector<pid_t> pids;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator("/proc", ec)) {
    const std::string name = e.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream f(e.path() / "cmdline");
    std::string cmd((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    if (cmd.find("plan-point") != std::string::npos &&
        cmd.find(out.string()) != std::string::npos) {
      std::ifstream stat(e.path() / "stat");
      std::string pid, comm, state;
      stat >> pid >> comm >> state;
      if (state != "Z") pids.push_back(std::stoi(name));
    }
  }
  return pids;
}

}  // namespace

TEST(PlanSafety, StoppingPlanStopsItsWorkersAndLeavesNoCompleteLookingDataset) {
  const fs::path dir = sonar3d::test::temp_dir("stop");
  // One point whose reconstruction takes seconds (fine voxels), with datasets kept.
  write(dir / "s.yaml",
        "seed: 3\nworkers: 1\nkeep_datasets: true\nelevation_step_deg: 0.1\n"
        "axes: {spacing_m: [0.05]}\n"
        "fixed: {aperture_deg: 10, fov_deg: 30, bearing_res_deg: 0.5, range_res_m: 0.04, "
        "voxel_m: 0.004, standoff_m: 2}\n");
  const fs::path out = dir / "out";
  const std::string exe = SONAR3D_CLI, s_yaml = (dir / "s.yaml").string(), s_out = out.string(),
                    log = (dir / "log.txt").string();
  std::vector<std::string> args = {exe, "plan", s_yaml, "-o", s_out, "-q"};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 2, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  pid_t plan = 0;
  ASSERT_EQ(posix_spawn(&plan, exe.c_str(), &fa, nullptr, argv.data(), environ), 0);
  posix_spawn_file_actions_destroy(&fa);
  // Wait until the point's dataset is simulated (the worker is reconstructing).
  const fs::path point = out / "points/p0000";
  const auto t0 = std::chrono::steady_clock::now();
  while (!fs::exists(point / "dataset.partial") && !fs::exists(point / "dataset") &&
         std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_TRUE(fs::exists(point / "dataset.partial") || fs::exists(point / "dataset"));
  const std::vector<pid_t> workers = plan_workers(out);
  ASSERT_EQ(workers.size(), 1u);
  ASSERT_EQ(kill(plan, SIGTERM), 0);
  int st = 0;
  ASSERT_EQ(waitpid(plan, &st, 0), plan);
  EXPECT_TRUE(WIFEXITED(st)) << "plan died of signal " << (WIFSIGNALED(st) ? WTERMSIG(st) : 0);
  EXPECT_EQ(WIFEXITED(st) ? WEXITSTATUS(st) : -1, 128 + SIGTERM);
  const std::string err = read_text_file(log);
  EXPECT_EQ(err.rfind("sonar3d: error: plan stopped by signal 15", 0), 0u) << err;
  // The worker is gone (not still writing into the output), its point failed, and no dataset of
  // the unfinished point looks complete.
  EXPECT_TRUE(plan_workers(out).empty());
  EXPECT_EQ(kill(workers[0], 0), -1);
  const auto status = nlohmann::json::parse(read_text_file((point / "status.json").string()));
  EXPECT_EQ(status["status"], "failed");
  EXPECT_NE(status["message"].get<std::string>().find("signal 15"), std::string::npos);
  EXPECT_FALSE(fs::exists(point / "dataset"));
  EXPECT_FALSE(fs::exists(point / "dataset.partial"));
}
