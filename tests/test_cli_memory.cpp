// Issue 29 item 5 through the command-line tool: memory estimated before allocating and refused
// beyond --max-memory, warnings for implausible values naming the flag, warnings on stderr only,
// hints naming flags rather than library fields.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "sonar3d/core/error.hpp"
#include "sonar3d/world/world_model.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;

namespace {

fs::path tmp_dir() {
  const fs::path d = fs::temp_directory_path() /
                     ("sonar3d_test_cli_memory_" +
                      std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
  return d;
}

struct CliRun : sonar3d::test::CliRunSplit {
  double seconds;      // wall clock
  double cpu_seconds;  // user + system time of the command
};

double children_cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_CHILDREN, &u);
  return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

CliRun run(const fs::path& dir, const std::string& args) {
  const auto t0 = std::chrono::steady_clock::now();
  const double cpu0 = children_cpu_seconds();
  CliRun r{sonar3d::test::run_cli_captured(dir, args), 0.0, 0.0};
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.cpu_seconds = children_cpu_seconds() - cpu0;
  return r;
}

class CliMemory : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = tmp_dir();
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  void TearDown() override { fs::remove_all(dir); }
  fs::path dir;
};

// A small dataset: a ball seen by one short vertical pass (the pass ends short of its top and
// bottom, so the bracketing assessment warns).
const char* kScene = R"(
seed: 2
sensor: {preset: sim-10deg, beams: 80, fov_deg: 40}
simulation: {elevation_step_deg: 0.05}
objects:
  - {name: ball, primitive: {type: sphere, radius: 0.4}, pose: {translation: [2.5, 0, 0]}, reflectivity: 0.9}
trajectory: {period: 0.1, type: straight, start: [0, 0, -0.3], end: [0, 0, 0.3], spacing: 0.05}
)";

}  // namespace

// The README tour's dataset (data/scenes/reference_objects.yaml) at 0.5 mm voxels: refused
// before anything is allocated, within a second, naming the estimate and the option to change.
// (Before: 75 s, 5.7 GB, std::bad_alloc.)
TEST_F(CliMemory, TourDatasetHalfMillimetreVoxelsRefusedWithEstimate) {
  const fs::path ds = dir / "ref";
  ASSERT_EQ(run(dir, std::string("simulate ") + SONAR3D_SOURCE_DIR +
                         "/data/scenes/reference_objects.yaml -o " + ds.string() + " -q")
                .code,
            0);
  for (const std::string method : {"carve", "deconv"}) {
    const fs::path out = dir / (method + ".ply");
    const CliRun r =
        run(dir, "reconstruct " + ds.string() + " --method " + method + " -o " + out.string() +
                     " --roi -3 -2 -0.03 3 14 3 --voxel-size 0.0005 -q");
    EXPECT_EQ(r.code, 1) << r.err;
    // Within a second of work: the CPU time is what the command costs (the wall clock is
    // bounded loosely, as ctest runs tests in parallel on shared machines).
    EXPECT_LT(r.cpu_seconds, 1.0) << method;
    EXPECT_LT(r.seconds, 10.0) << method;
    EXPECT_NE(r.err.find("needs an estimated"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(" GB"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("--voxel-size"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("--max-memory"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_FALSE(fs::exists(out));
  }
  // The estimate is computed from the options: at 1 cm it fits the default limit, and a lower
  // --max-memory refuses it too, with a smaller estimate.
  const CliRun r = run(dir, "reconstruct " + ds.string() + " -o " + (dir / "c.ply").string() +
                                " --roi -3 -2 -0.03 3 14 3 --voxel-size 0.01 --max-memory 0.05 -q");
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("needs an estimated"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("MB"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--voxel-size"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("fits"), std::string::npos) << r.err;  // the voxel size that fits
}

// Warnings and notes go to stderr; stdout carries only the results. --voxel-size 1 (centimetres
// meant) is warned about, naming the flag.
TEST_F(CliMemory, WarningsNeverReachStdout) {
  std::ofstream(dir / "scene.yaml") << kScene;
  const fs::path ds = dir / "ds";
  ASSERT_EQ(
      run(dir, "simulate " + (dir / "scene.yaml").string() + " -o " + ds.string() + " -q").code, 0);
  for (const std::string args :
       {"--method carve", "--method carve --voxel-size 1 --allow-empty",
        "--method deconv --allow-empty", "--method deconv --deconv-mode passes --allow-empty"}) {
    const fs::path out = dir / "out.ply";
    fs::remove(out);
    const CliRun r =
        run(dir, "reconstruct " + ds.string() + " " + args + " -o " + out.string() + " -q");
    EXPECT_EQ(r.code, 0) << args << ": " << r.err;
    EXPECT_EQ(r.out.find("warning"), std::string::npos) << args << ": " << r.out;
    EXPECT_EQ(r.out.find("note"), std::string::npos) << args << ": " << r.out;
    EXPECT_NE(r.out.find("ply"), std::string::npos) << args << ": " << r.out;  // the result
    if (args.find("carve") != std::string::npos) {  // the pass ends short: warned on stderr
      EXPECT_NE(r.err.find("sonar3d: warning: "), std::string::npos) << args << ": " << r.err;
    }
    if (args.find("--voxel-size 1") != std::string::npos) {
      EXPECT_NE(r.err.find("--voxel-size 1 m is"), std::string::npos) << r.err;
      EXPECT_NE(r.err.find("centimetres"), std::string::npos) << r.err;
    }
  }
  // evaluate --coverage-radius 3 (above the scene's scale: a 0.8 m ball) is warned about.
  ASSERT_EQ(run(dir, "reconstruct " + ds.string() + " -o " + (dir / "c.ply").string() + " -q").code,
            0);
  const CliRun r = run(dir, "evaluate " + (dir / "c.ply").string() + " --truth " + ds.string() +
                                " --coverage-radius 3");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("sonar3d: warning: --coverage-radius 3 m is at least half the size of "
                       "object 'ball'"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.out.find("warning"), std::string::npos) << r.out;
}

// Errors from a library's validation name the user's flag, not the config field.
TEST_F(CliMemory, HintsNameFlags) {
  std::ofstream(dir / "scene.yaml") << kScene;
  const fs::path ds = dir / "ds";
  ASSERT_EQ(
      run(dir, "simulate " + (dir / "scene.yaml").string() + " -o " + ds.string() + " -q").code, 0);
  CliRun r = run(dir, "reconstruct " + ds.string() + " -o " + (dir / "a.ply").string() +
                          " --carve-margin 2 -q");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--carve-margin must lie in [0, 1]"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("carve."), std::string::npos) << r.err;
  r = run(dir, "reconstruct " + ds.string() + " --method deconv -o " + (dir / "a.ply").string() +
                   " --lambda 3 -q");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--lambda"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("deconv.lambda"), std::string::npos) << r.err;
  // elevation: the cell size and the memory limit name --cell-m.
  r = run(dir, "reconstruct " + ds.string() + " -o " + (dir / "c.ply").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.err;
  r = run(dir, "elevation " + (dir / "c.ply").string() + " -o " + (dir / "e.tif").string() +
                   " --cell-m 1e-6");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("needs an estimated"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("change --cell-m"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("cell_m"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "e.tif"));
}

// Errors that leaked a library's words become one line naming the file and the key (issue 29
// item 4, "while there").
TEST_F(CliMemory, LibraryWordsBecomeOneLineNamingFileAndKey) {
  // A non-UTF-8 name in a catalogue (was "[json.exception.type_error.316] invalid UTF-8 byte").
  std::ofstream(dir / "cat.yaml") << "models:\n  - {name: \"ab\xff\", reference: sphere}\n";
  std::ofstream(dir / "cloud.ply") << "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                                      "property float y\nproperty float z\nend_header\n0 0 0\n";
  CliRun r = run(dir, "recognize " + (dir / "cloud.ply").string() + " --catalogue " +
                          (dir / "cat.yaml").string() + " -o " + (dir / "p.json").string() + " -q");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("cat.yaml:2: key 'models[0].name'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("not valid UTF-8"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("json.exception"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  // The same in a connections file, and an unknown top-level key there is an error too.
  std::ofstream(dir / "c1.yaml") << "connections:\n  - {from: \"a\xfe\", to: b}\n";
  EXPECT_THROW(
      {
        try {
          sonar3d::read_given_connections((dir / "c1.yaml").string());
        } catch (const sonar3d::Error& e) {
          EXPECT_NE(std::string(e.what()).find("c1.yaml:2: key 'connection.from'"),
                    std::string::npos)
              << e.what();
          throw;
        }
      },
      sonar3d::Error);
  std::ofstream(dir / "c2.yaml") << "connections:\n  - {from: a, to: b}\nconections_extra: 1\n";
  EXPECT_THROW(
      {
        try {
          sonar3d::read_given_connections((dir / "c2.yaml").string());
        } catch (const sonar3d::Error& e) {
          EXPECT_NE(std::string(e.what()).find("conections_extra"), std::string::npos) << e.what();
          EXPECT_NE(std::string(e.what()).find("unknown key"), std::string::npos) << e.what();
          throw;
        }
      },
      sonar3d::Error);
  // A file name longer than the file system takes (was "filesystem error: ... File name too
  // long" or GDAL's words with the temporary name twice).
  r = run(dir, "elevation " + (dir / "cloud.ply").string() + " -o " +
                   (dir / (std::string(300, 'x') + ".tif")).string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("bytes long"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("(-o)"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("filesystem error"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  // A path through a regular file (was a raw "Not a directory").
  r = run(dir, "evaluate " + (dir / "cloud.ply").string() + " --truth " +
                   (dir / "cloud.ply" / "mesh.ply").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("cloud.ply/mesh.ply"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("filesystem error"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

// recognize, world and diff estimate their grids from their cell options and the map's extent
// before allocating (issue 29 item 5): a cell given in the wrong unit is refused at once with the
// estimate and the flag, and nothing is written.
TEST_F(CliMemory, RecognizeWorldAndDiffRefuseGridsBeyondTheLimit) {
  // A 20 x 20 m seabed sampled every 0.5 m, a catalogue of one model, one placement.
  {
    std::ofstream ply(dir / "map.ply");
    ply << "ply\nformat ascii 1.0\nelement vertex 1681\nproperty float x\nproperty float y\n"
           "property float z\nend_header\n";
    for (int i = 0; i <= 40; ++i) {
      for (int j = 0; j <= 40; ++j) ply << 0.5 * i << ' ' << 0.5 * j << " 0\n";
    }
  }
  std::ofstream(dir / "cat.yaml") << "models:\n  - {name: tank, reference: tank}\n";
  std::ofstream(dir / "p.json")
      << R"({"format": "sonar3d-placements", "version": 1, "map": "m", "catalogue": "c",
             "placements": [{"model": "tank", "T_world_model": [[1, 0, 0, 10], [0, 1, 0, 10],
             [0, 0, 1, 0], [0, 0, 0, 1]], "score_m": 0.3, "residual_median_m": null}]})";
  const std::string map = (dir / "map.ply").string(), cat = (dir / "cat.yaml").string();
  auto refused = [&](const std::string& args, const std::string& flag, const fs::path& out) {
    const CliRun r = run(dir, args + " -q");
    EXPECT_EQ(r.code, 1) << args << "\n" << r.err;
    EXPECT_LT(r.cpu_seconds, 1.0) << args;
    EXPECT_NE(r.err.find("needs an estimated"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(flag), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("--max-memory"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(out)) << out;
  };
  const fs::path p = dir / "found.json";
  // 50 µm cells (millimetres meant as metres, twice over): 1.6e11 cells of the fine map.
  refused("recognize " + map + " --catalogue " + cat + " -o " + p.string() + " --map-cell 0.00005",
          "--map-cell", p);
  refused("recognize " + map + " --catalogue " + cat + " -o " + p.string() +
              " --method 3d --subsample 0.00005",
          "--subsample", p);
  refused("world " + map + " --placements " + (dir / "p.json").string() + " --catalogue " + cat +
              " -o " + (dir / "W").string() + " --lod-cells 0.00005,0.0001",
          "--lod-cells", dir / "W");
  // diff: 5 mm change cells over 20 x 20 m fit the default limit but not 100 MB.
  refused(
      "diff " + map + " " + map + " -o " + (dir / "D").string() + " --cell 0.005 --max-memory 0.1",
      "--cell", dir / "D");
  // At their defaults all three fit the default limit: the estimates are not what refuses.
  const CliRun ok = run(dir, "diff " + map + " " + map + " -o " + (dir / "D2").string() + " -q");
  EXPECT_EQ(ok.err.find("needs an estimated"), std::string::npos) << ok.err;
}
