#pragma once
// Progress of long calls (simulate, carve, deconvolve, reconstruct, imports, plan, report).
//
// Progress is a terminal bar (done/total, rate, time left) on stderr, silent when stderr is not a
// terminal or when disabled (--quiet). Thread-safe increments.
//
// A program that shows progress its own way (a notebook, a GUI; the Python bindings) installs a
// ScopedProgressCallback around the call: every Progress constructed on that thread while the
// scope lives also reports (label, done, total) to the callback, whether or not the terminal bar
// is enabled. A call may go through several stages, each a Progress with its own label and total
// (e.g. "read+denoise" then "deconvolve"). The callback receives (label, 0, total) when a stage
// starts, then updates at most every 100 ms from whichever thread advanced it (never two calls at
// once), and (label, done, total) when the stage finishes. It must not throw.
#include <atomic>
#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

namespace sonar3d {

using ProgressCallback =
    std::function<void(const std::string& label, std::size_t done, std::size_t total)>;

class Progress {
 public:
  Progress(std::string label, std::size_t total, bool enabled = true);
  ~Progress();
  void add(std::size_t n = 1);
  void finish();
  static bool stderr_is_terminal();

 private:
  void draw(bool final_line);
  void report();  // with callback_mutex_ held
  std::string label_;
  std::size_t total_;
  bool enabled_;
  std::atomic<std::size_t> done_{0};
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
  std::chrono::steady_clock::time_point last_report_;
  std::mutex mutex_;
  std::mutex callback_mutex_;
  bool finished_ = false;                             // with mutex_
  bool reported_final_ = false;                       // with callback_mutex_
  std::shared_ptr<const ProgressCallback> callback_;  // the thread's callback at construction
};

// Installs `callback` for the Progress objects constructed on the calling thread until the scope
// ends (scopes nest; the previous callback comes back). An empty callback disables reporting.
class ScopedProgressCallback {
 public:
  explicit ScopedProgressCallback(ProgressCallback callback);
  ~ScopedProgressCallback();
  ScopedProgressCallback(const ScopedProgressCallback&) = delete;
  ScopedProgressCallback& operator=(const ScopedProgressCallback&) = delete;

 private:
  std::shared_ptr<const ProgressCallback> previous_;
};

}  // namespace sonar3d
