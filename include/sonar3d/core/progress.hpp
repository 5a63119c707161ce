#pragma once
// A terminal progress bar (done/total, rate, time left) on stderr. Silent when stderr is not a
// terminal or when disabled (--quiet). Thread-safe increments.
#include <atomic>
#include <chrono>
#include <mutex>
#include <string>

namespace sonar3d {

class Progress {
 public:
  Progress(std::string label, std::size_t total, bool enabled = true);
  ~Progress();
  void add(std::size_t n = 1);
  void finish();
  static bool stderr_is_terminal();

 private:
  void draw(bool final_line);
  std::string label_;
  std::size_t total_;
  bool enabled_;
  std::atomic<std::size_t> done_{0};
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
  std::mutex mutex_;
  bool finished_ = false;
};

}  // namespace sonar3d
