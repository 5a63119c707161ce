// core/progress: the callback hook (ScopedProgressCallback) that notebooks and GUIs use, through
// a real long call (reconstruct_dataset on a small simulated pass) and on its own.
#include <gtest/gtest.h>

#include <atomic>
#include <fstream>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "sonar3d/core/progress.hpp"
#include "sonar3d/recon/reconstruct.hpp"
#include "sonar3d/sim/simulation.hpp"
#include "test_support.hpp"

using namespace sonar3d;
namespace fs = std::filesystem;

namespace {

struct Call {
  std::string label;
  std::size_t done, total;
};

struct Recorder {
  std::mutex mutex;
  std::vector<Call> calls;
  std::atomic<int> inside{0};
  bool overlapped = false;
  ProgressCallback callback() {
    return [this](const std::string& label, std::size_t done, std::size_t total) {
      if (inside.fetch_add(1) != 0) overlapped = true;
      {
        std::lock_guard<std::mutex> lock(mutex);
        calls.push_back({label, done, total});
      }
      inside.fetch_sub(1);
    };
  }
};

}  // namespace

TEST(Progress, CallbackSeesEveryStageFromStartToEnd) {
  Recorder rec;
  {
    ScopedProgressCallback scope(rec.callback());
    Progress p("work", 1000, /*enabled=*/false);  // no terminal bar, the callback still reports
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t) {
      threads.emplace_back([&] {
        for (int k = 0; k < 250; ++k) p.add();
      });
    }
    for (auto& t : threads) t.join();
    p.finish();
    p.finish();  // once only
  }
  ASSERT_GE(rec.calls.size(), 2u);
  EXPECT_EQ(rec.calls.front().done, 0u);
  EXPECT_EQ(rec.calls.back().done, 1000u);
  EXPECT_EQ(rec.calls.back().total, 1000u);
  for (std::size_t k = 1; k < rec.calls.size(); ++k) {
    EXPECT_EQ(rec.calls[k].label, "work");
    EXPECT_LE(rec.calls[k - 1].done, rec.calls[k].done);
  }
  EXPECT_FALSE(rec.overlapped);

  // Outside the scope, and on another thread, nothing reports.
  const std::size_t n = rec.calls.size();
  { Progress p("later", 3); }
  {
    ScopedProgressCallback scope(rec.callback());
    std::thread([] { Progress p("other thread", 3); }).join();
  }
  EXPECT_EQ(rec.calls.size(), n);
}

TEST(Progress, ScopesNest) {
  Recorder outer, inner;
  ScopedProgressCallback a(outer.callback());
  {
    ScopedProgressCallback b(inner.callback());
    Progress p("inner", 1);
  }
  { Progress p("outer", 1); }
  ASSERT_FALSE(inner.calls.empty());
  ASSERT_FALSE(outer.calls.empty());
  EXPECT_EQ(inner.calls.back().label, "inner");
  EXPECT_EQ(outer.calls.front().label, "outer");
  EXPECT_EQ(outer.calls.size(), 2u);  // (0, 1) and (1, 1)
}

TEST(Progress, ReconstructReportsEachStageOfCarvingAndDeconvolution) {
  const fs::path dir = test::temp_dir("progress");
  std::ofstream(dir / "scene.yaml") << R"(
seed: 5
sensor: {preset: sim-10deg, fov_deg: 30, beams: 75, r_min: 1.0, r_max: 3.0, range_bins: 100}
simulation: {elevation_step_deg: 0.02, gain: 2.0}
objects:
  - {name: ball, primitive: {type: sphere, radius: 0.5}, pose: {translation: [0, 0, 0]}, reflectivity: 0.8}
trajectory: {period: 0.1, type: straight, start: [-2, 0, -0.7], end: [-2, 0, 0.7], spacing: 0.02}
)";
  Recorder sim;
  {
    ScopedProgressCallback scope(sim.callback());
    simulate_dataset(load_simulation_setup((dir / "scene.yaml").string()), dir / "ds", false);
  }
  ASSERT_FALSE(sim.calls.empty());
  EXPECT_EQ(sim.calls.front().label, "simulate");
  const std::size_t frames = sim.calls.back().total;
  EXPECT_EQ(sim.calls.back().done, frames);

  const Dataset ds = read_dataset(dir / "ds");
  ASSERT_EQ(ds.size(), frames);
  for (const std::string method : {"carve", "deconv"}) {
    Recorder rec;
    ReconstructOptions o;
    o.method = method;
    o.voxel_size = 0.02;
    o.region = Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1, 1, 1));
    ReconstructResult r;
    {
      ScopedProgressCallback scope(rec.callback());
      r = reconstruct_dataset(ds, o);
    }
    EXPECT_EQ(r.method, method);
    EXPECT_GT(r.cloud.size(), 100u);
    EXPECT_NE(r.report.find("\"frames\""), std::string::npos) << r.report;
    // Each stage starts at 0 and ends complete.
    std::map<std::string, std::vector<Call>> stages;
    for (const auto& c : rec.calls) stages[c.label].push_back(c);
    const std::vector<std::string> expected =
        method == "carve" ? std::vector<std::string>{"carve", "occlusions"}
                          : std::vector<std::string>{"read+denoise", "deconvolve"};
    for (const auto& label : expected) {
      ASSERT_TRUE(stages.count(label)) << method << ": no stage " << label;
      const auto& s = stages[label];
      EXPECT_EQ(s.front().done, 0u) << label;
      EXPECT_EQ(s.back().done, s.back().total) << label;
      EXPECT_GT(s.back().total, 0u) << label;
    }
    EXPECT_FALSE(rec.overlapped);
  }
  fs::remove_all(dir);
}
