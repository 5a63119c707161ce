// Runs a sweep: subprocess per point (failure isolation and per-point peak memory), resumable,
// parallel on this machine, spread over MPI ranks when launched under mpirun.
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstring>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <thread>

#include "plan_internal.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/core/progress.hpp"

extern char** environ;
namespace fs = std::filesystem;

namespace sonar3d {

std::string plan_params_key(const std::map<std::string, SweepValue>& params) {
  std::string key;
  for (const auto& kv : params) key += kv.first + "=" + to_string(kv.second) + ";";
  return key;
}

nlohmann::json plan_params_json(const std::map<std::string, SweepValue>& params) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& kv : params) {
    if (std::holds_alternative<std::monostate>(kv.second)) {
      j[kv.first] = nullptr;
    } else if (const auto* d = std::get_if<double>(&kv.second)) {
      j[kv.first] = *d;
    } else {
      j[kv.first] = std::get<std::string>(kv.second);
    }
  }
  return j;
}

int plan_threads_per_point() {
  const char* v = std::getenv("SONAR3D_PLAN_THREADS");
  return v ? std::max(0, std::atoi(v)) : 0;
}

namespace {

std::optional<nlohmann::json> read_status(const fs::path& file) {
  if (!fs::exists(file)) return std::nullopt;
  try {
    return nlohmann::json::parse(read_text_file(file.string()));
  } catch (const std::exception&) {
    return std::nullopt;  // a damaged status is treated as unfinished
  }
}

// SIGINT/SIGTERM while the planner runs: remember the signal and forward it to the workers, so
// that none goes on writing into the output after `plan` was stopped. The handler only reads the
// pid table (async-signal-safe); workers are registered with these signals blocked.
volatile std::sig_atomic_t g_stop_signal = 0;
std::atomic<pid_t>* g_workers = nullptr;
std::size_t g_worker_slots = 0;

extern "C" void forward_stop_signal(int sig) {
  g_stop_signal = sig;
  for (std::size_t i = 0; i < g_worker_slots; ++i) {
    const pid_t pid = g_workers[i].load();
    if (pid > 0) ::kill(pid, sig);
  }
}

// Installs forward_stop_signal for SIGINT and SIGTERM (unless they are ignored, as in a
// background job) and restores the previous handlers when destroyed.
class StopSignalForwarding {
 public:
  explicit StopSignalForwarding(std::vector<std::atomic<pid_t>>& slots) {
    g_stop_signal = 0;
    g_workers = slots.data();
    g_worker_slots = slots.size();
    for (int i = 0; i < 2; ++i) {
      struct sigaction sa {};
      sa.sa_handler = forward_stop_signal;
      sigemptyset(&sa.sa_mask);
      sa.sa_flags = 0;  // no SA_RESTART: wait4() returns EINTR
      ::sigaction(kSignals[i], nullptr, &old_[i]);
      installed_[i] = old_[i].sa_handler != SIG_IGN && ::sigaction(kSignals[i], &sa, nullptr) == 0;
    }
  }
  ~StopSignalForwarding() {
    for (int i = 0; i < 2; ++i) {
      if (installed_[i]) ::sigaction(kSignals[i], &old_[i], nullptr);
    }
    g_worker_slots = 0;
    g_workers = nullptr;
  }
  StopSignalForwarding(const StopSignalForwarding&) = delete;
  StopSignalForwarding& operator=(const StopSignalForwarding&) = delete;
  static constexpr int kSignals[2] = {SIGINT, SIGTERM};

 private:
  struct sigaction old_[2]{};
  bool installed_[2] = {false, false};
};

// Blocks SIGINT/SIGTERM in this thread while alive (a worker is spawned and registered as one
// step, so that the forwarding handler cannot miss it).
class BlockStopSignals {
 public:
  BlockStopSignals() {
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    ::pthread_sigmask(SIG_BLOCK, &set, &old_);
  }
  ~BlockStopSignals() { ::pthread_sigmask(SIG_SETMASK, &old_, nullptr); }
  const sigset_t& previous() const { return old_; }

 private:
  sigset_t old_;
};

// Spawns `exe plan-point DIR INDEX` with the signal mask `mask`; returns the pid.
pid_t spawn_point(const std::string& exe, const fs::path& dir, std::size_t index, int threads,
                  const sigset_t& mask) {
  const std::string s_dir = dir.string(), s_idx = std::to_string(index);
  std::vector<std::string> args = {exe, "plan-point", s_dir, s_idx};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::vector<std::string> env_store;
  for (char** e = environ; *e; ++e) {
    if (std::string(*e).rfind("SONAR3D_PLAN_THREADS=", 0) != 0) env_store.emplace_back(*e);
  }
  env_store.push_back("SONAR3D_PLAN_THREADS=" + std::to_string(threads));
  std::vector<char*> envp;
  for (auto& e : env_store) envp.push_back(e.data());
  envp.push_back(nullptr);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  posix_spawnattr_setsigmask(&attr, &mask);  // the worker starts with the caller's usual mask
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, exe.c_str(), nullptr, &attr, argv.data(), envp.data());
  posix_spawnattr_destroy(&attr);
  if (rc != 0) {
    throw Error("cannot start the worker '" + exe + "': " + std::strerror(rc));
  }
  return pid;
}

// Records what the parent saw of a finished child: peak memory, and a failure if the child died
// (signal, non-zero exit) or exited without writing its status. Whatever a worker that died
// wrote is not trusted: it may have been killed after writing "ok", or by `plan` being stopped.
// A failed point's dataset is removed (with the temporaries of the dead worker).
void finish_point(const fs::path& dir, std::size_t index, int wstatus, const rusage& ru,
                  const std::string& key) {
  const fs::path point_dir = dir / "points" / point_id(index);
  const fs::path file = point_dir / "status.json";
  auto st = read_status(file);
  const bool died = !WIFEXITED(wstatus) || WEXITSTATUS(wstatus) != 0;
  if (died || !st || (*st).value("params_key", "") != key) {
    nlohmann::json j;
    j["id"] = point_id(index);
    j["index"] = index;
    j["params_key"] = key;
    j["status"] = "failed";
    std::ostringstream msg;
    if (WIFSIGNALED(wstatus)) {
      msg << "worker killed by signal " << WTERMSIG(wstatus) << " (" << strsignal(WTERMSIG(wstatus))
          << ")";
      if (g_stop_signal) msg << ": the planner was stopped; run it again to resume";
    } else if (WIFEXITED(wstatus) && WEXITSTATUS(wstatus) != 0) {
      msg << "worker exited with status " << WEXITSTATUS(wstatus);
      if (st && st->contains("message") && (*st)["message"].is_string())
        msg << ": " << (*st)["message"].get<std::string>();
    } else {
      msg << "worker exited without a result";
    }
    j["message"] = msg.str();
    st = j;
    fs::create_directories(file.parent_path());
  }
  if ((*st).value("status", "") != "ok") {
    std::error_code ec;
    for (const fs::path& ds : {point_dir / kPartialDatasetName, point_dir / "dataset"}) {
      recover_interrupted_writes(ds);  // the dead worker's temporaries
      fs::remove_all(ds, ec);
    }
  }
  (*st)["peak_rss_mb"] = ru.ru_maxrss / 1024.0;  // ru_maxrss is in KiB on Linux
  write_text_file(file.string(), st->dump(2) + "\n");
}

// A point's parameters satisfy every hard constraint of the sweep.
bool within_constraints(const Sweep& sweep, const std::map<std::string, SweepValue>& params) {
  for (const auto& c : sweep.constraints) {
    if (!c.satisfied_by(params)) return false;
  }
  return true;
}

// Workers that run `points` points together: the sweep's, else one per core, at most one per
// point.
int sweep_workers(const Sweep& sweep, std::size_t points) {
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  return std::max(1, std::min<int>(sweep.workers > 0 ? sweep.workers : cores,
                                   static_cast<int>(std::max<std::size_t>(1, points))));
}

// Refuses the sweep, before any point runs, when its largest point's reconstruction (estimated
// from the point's simulated poses and its voxel, core/memory.hpp) times the workers that run
// together exceeds the memory limit; the refusal names the point and its voxel_m.
void check_sweep_memory(const Sweep& sweep, const PlanOptions& opt) {
  const double limit =
      opt.max_memory_bytes > 0 ? opt.max_memory_bytes : default_memory_limit_bytes();
  // This rank's points within the constraints (finished ones included: a resumed sweep is
  // judged as a new one would be), and the workers that run them together (as run_sweep).
  std::vector<std::size_t> todo;
  for (std::size_t i = 0; i < sweep.size(); ++i) {
    if (static_cast<int>(i % opt.mpi_size) != opt.mpi_rank) continue;
    if (within_constraints(sweep, sweep.point(i))) todo.push_back(i);
  }
  const int workers = sweep_workers(sweep, todo.size());
  const fs::path dir = sweep.source.empty() ? opt.out_dir : fs::path(sweep.source).parent_path();
  MemoryEstimate largest;
  std::size_t which = 0;
  for (const std::size_t i : todo) {
    const auto params = sweep.point(i);
    MemoryEstimate e;
    try {
      e = estimate_plan_point_memory(plan_setup(sweep, params, dir), params,
                                     limit / std::max(1, workers));
    } catch (const Error&) {
      continue;  // a configuration that cannot be set up fails as its own point, recorded
    }
    if (e.total() > largest.total()) largest = e, which = i;
  }
  if (largest.parts.empty()) return;
  MemoryEstimate all;
  for (const auto& p : largest.parts) {
    all.add("point " + point_id(which) + ", " + std::to_string(workers) + " at a time: " + p.what,
            p.bytes * workers, p.option);
  }
  std::string advice = largest.advice;  // "--voxel-size 0.0012 fits": the sweep's voxel_m
  for (std::size_t k; (k = advice.find("--voxel-size")) != std::string::npos;) {
    advice.replace(k, 12, "voxel_m");
  }
  all.advice = advice.empty() ? "or fewer workers" : advice + ", or fewer workers";
  check_memory(all, limit, "plan");
}

}  // namespace

PlanSummary run_sweep(const Sweep& sweep, const PlanOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  if (opt.worker_executable.empty() || !fs::exists(opt.worker_executable)) {
    throw Error("planner: worker executable '" + opt.worker_executable + "' not found");
  }
  check_sweep_memory(sweep, opt);  // before anything is written
  fs::create_directories(opt.out_dir / "points");
  if (opt.mpi_rank == 0) {
    // The copy every worker reads: the sweep's own directory anchors relative mesh paths.
    std::string text = read_text_file(sweep.source);
    write_text_file((opt.out_dir / "sweep.yaml").string(), text);
  }
  PlanSummary sum;
  sum.points = sweep.size();
  std::vector<std::size_t> todo;
  for (std::size_t i = 0; i < sweep.size(); ++i) {
    if (static_cast<int>(i % opt.mpi_size) != opt.mpi_rank) continue;  // MPI: round-robin
    const auto params = sweep.point(i);
    const std::string key = plan_params_key(params);
    const fs::path status = opt.out_dir / "points" / point_id(i) / "status.json";
    if (!within_constraints(sweep, params)) {
      nlohmann::json j = {{"id", point_id(i)},
                          {"index", i},
                          {"params_key", key},
                          {"params", plan_params_json(params)},
                          {"status", "skipped_constraint"},
                          {"message", "violates a hard constraint"}};
      fs::create_directories(status.parent_path());
      write_text_file(status.string(), j.dump(2) + "\n");
      ++sum.skipped_constraint;
      continue;
    }
    const auto st = read_status(status);
    if (st && (*st).value("params_key", "") == key && (*st).value("status", "") == "ok") {
      ++sum.skipped_done;  // resumable: finished points are kept
      continue;
    }
    todo.push_back(i);
  }
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const int workers = sweep_workers(sweep, todo.size());
  const int threads = std::max(1, cores / workers);
  Progress bar("plan", todo.size(), opt.progress);
  std::map<pid_t, std::size_t> running;
  std::vector<std::atomic<pid_t>> slots(static_cast<std::size_t>(workers));
  for (auto& p : slots) p = 0;
  StopSignalForwarding forwarding(slots);
  std::size_t next = 0;
  auto launch = [&] {
    while (static_cast<int>(running.size()) < workers && next < todo.size()) {
      BlockStopSignals block;
      if (g_stop_signal) return;  // stopped: start nothing new
      const std::size_t i = todo[next++];
      const pid_t pid =
          spawn_point(opt.worker_executable, opt.out_dir, i, threads, block.previous());
      for (auto& slot : slots) {
        if (slot.load() == 0) {
          slot = pid;
          break;
        }
      }
      running[pid] = i;
    }
  };
  launch();
  while (!running.empty()) {
    int wstatus = 0;
    rusage ru{};
    const pid_t pid = wait4(-1, &wstatus, 0, &ru);
    if (pid < 0) {
      if (errno == EINTR) continue;  // a stop signal: forwarded, the workers are exiting
      throw Error(std::string("planner: waiting for workers failed: ") + std::strerror(errno));
    }
    const auto it = running.find(pid);
    if (it == running.end()) continue;
    for (auto& slot : slots) {
      if (slot.load() == pid) slot = 0;
    }
    const std::size_t i = it->second;
    running.erase(it);
    finish_point(opt.out_dir, i, wstatus, ru, plan_params_key(sweep.point(i)));
    const auto st = read_status(opt.out_dir / "points" / point_id(i) / "status.json");
    if (!st || (*st).value("status", "") != "ok") ++sum.failed;
    ++sum.ran;
    bar.add();
    launch();
  }
  bar.finish();
  if (const int sig = g_stop_signal) {
    throw Interrupted("plan stopped by signal " + std::to_string(sig) + " (" + strsignal(sig) +
                          "): its workers were stopped and their points recorded as failed; " +
                          "finished points are kept, run the same command to resume",
                      sig);
  }
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return sum;
}

std::size_t write_sweep_results(const Sweep& sweep, const fs::path& dir) {
  // ordered_json keeps the axes in the sweep file's order (the report's plots follow it).
  nlohmann::ordered_json results;
  results["format"] = json_format_marker(OutputKind::PlanResultsJson);
  results["version"] = 1;
  results["rank_by"] = sweep.rank_by;
  const bool higher = metric_higher_is_better(sweep.rank_by);
  results["rank_order"] = higher ? "descending" : "ascending";
  results["constraints"] = nlohmann::ordered_json::array();
  for (const auto& c : sweep.constraints) results["constraints"].push_back(c.text);
  results["axes"] = nlohmann::ordered_json::object();
  for (const auto& [name, values] : sweep.axes) {
    nlohmann::ordered_json list = nlohmann::ordered_json::array();
    for (const auto& v : values) {
      if (std::holds_alternative<std::monostate>(v)) {
        list.push_back(nullptr);
      } else if (const auto* d = std::get_if<double>(&v)) {
        list.push_back(*d);
      } else {
        list.push_back(std::get<std::string>(v));
      }
    }
    results["axes"][name] = list;
  }
  std::vector<nlohmann::json> points;
  for (std::size_t i = 0; i < sweep.size(); ++i) {
    const auto params = sweep.point(i);
    auto st = read_status(dir / "points" / point_id(i) / "status.json");
    nlohmann::json p;
    p["id"] = point_id(i);
    p["params"] = plan_params_json(params);
    if (!st || (*st).value("params_key", "") != plan_params_key(params)) {
      p["status"] = "missing";
      p["message"] = "not run yet";
    } else {
      for (const char* k : {"status", "message", "metrics", "runtime_s", "peak_rss_mb",
                            "data_bytes", "cloud", "objects", "frames"}) {
        if (st->contains(k)) p[k] = (*st)[k];
      }
    }
    if (!p.contains("cloud")) p["cloud"] = nullptr;
    p["rank"] = nullptr;
    points.push_back(p);
  }
  // Rank the points that ran, satisfy the constraints and have the metric.
  auto metric_of = [&](const nlohmann::json& p) -> std::optional<double> {
    const std::string& m = sweep.rank_by;
    const nlohmann::json* v = nullptr;
    if (p.contains("metrics") && p["metrics"].contains(m)) v = &p["metrics"][m];
    if (p.contains(m)) v = &p[m];
    if (!v || !v->is_number()) return std::nullopt;
    const double x = v->get<double>();
    return std::isfinite(x) ? std::optional<double>(x) : std::nullopt;
  };
  std::vector<std::size_t> order;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (points[i].value("status", "") == "ok" && metric_of(points[i])) order.push_back(i);
  }
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return higher ? *metric_of(points[a]) > *metric_of(points[b])
                  : *metric_of(points[a]) < *metric_of(points[b]);
  });
  for (std::size_t r = 0; r < order.size(); ++r) points[order[r]]["rank"] = r + 1;
  results["points"] = nlohmann::ordered_json::parse(nlohmann::json(points).dump());
  const std::string results_json = results.dump(2) + "\n";

  // results.csv: one row per point.
  std::ostringstream csv;
  csv << "id,status,rank";
  for (const auto& name : sweep_parameter_names()) csv << ',' << name;
  const std::vector<std::string> mcols = {"median_error_m", "mean_error_m",       "coverage",
                                          "outliers",       "median_to_coverage", "num_points"};
  for (const auto& m : mcols) csv << ',' << m;
  csv << ",runtime_s,peak_rss_mb,data_bytes,message\n";
  auto cell = [](const nlohmann::json& v) -> std::string {
    if (v.is_null()) return "";
    if (v.is_string()) return v.get<std::string>();
    std::ostringstream os;
    os.precision(8);
    if (v.is_number_integer()) {
      os << v.get<long long>();
    } else if (v.is_number()) {
      os << v.get<double>();
    } else {
      os << v.dump();
    }
    return os.str();
  };
  auto quoted = [](std::string s) {
    std::string out = "\"";
    for (char c : s) out += (c == '"') ? std::string("\"\"") : std::string(1, c == '\n' ? ' ' : c);
    return out + "\"";
  };
  for (const auto& p : points) {
    csv << p["id"].get<std::string>() << ',' << p.value("status", "") << ',' << cell(p["rank"]);
    for (const auto& name : sweep_parameter_names()) csv << ',' << cell(p["params"][name]);
    for (const auto& m : mcols) {
      csv << ','
          << (p.contains("metrics") && p["metrics"].contains(m) ? cell(p["metrics"][m]) : "");
    }
    for (const char* k : {"runtime_s", "peak_rss_mb", "data_bytes"}) {
      csv << ',' << (p.contains(k) ? cell(p[k]) : "");
    }
    csv << ',' << quoted(p.value("message", "")) << '\n';
  }
  // results.json and results.csv appear together (the output rule, core/output_dir.hpp); they
  // are the plan directory's own, replaced on every run.
  OutputPolicy policy;
  policy.overwrite = true;
  OutputFiles out(policy);
  const fs::path json_tmp = out.add(dir / "results.json", OutputKind::PlanResultsJson, "-o");
  const fs::path csv_tmp = out.add(dir / "results.csv", OutputKind::PlanResultsCsv, "-o");
  write_text_file(json_tmp.string(), results_json);
  write_text_file(csv_tmp.string(), csv.str());
  out.commit();
  std::size_t ok = 0;
  for (const auto& p : points) ok += p.value("status", "") == "ok";
  return ok;
}

}  // namespace sonar3d
