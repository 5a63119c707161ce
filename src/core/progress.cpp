#include "sonar3d/core/progress.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace sonar3d {

namespace {
// The callback of ScopedProgressCallback, per thread.
thread_local std::shared_ptr<const ProgressCallback> t_callback;
constexpr auto kInterval = std::chrono::milliseconds(100);  // redraw / report at most 10 Hz
}  // namespace

ScopedProgressCallback::ScopedProgressCallback(ProgressCallback callback)
    : previous_(std::move(t_callback)) {
  if (callback) t_callback = std::make_shared<const ProgressCallback>(std::move(callback));
}

ScopedProgressCallback::~ScopedProgressCallback() { t_callback = std::move(previous_); }

bool Progress::stderr_is_terminal() { return ::isatty(STDERR_FILENO) == 1; }

Progress::Progress(std::string label, std::size_t total, bool enabled)
    : label_(std::move(label)),
      total_(total),
      enabled_(enabled && stderr_is_terminal()),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_),
      last_report_(start_),
      callback_(t_callback) {
  if (callback_) (*callback_)(label_, 0, total_);
}

Progress::~Progress() { finish(); }

void Progress::add(std::size_t n) {
  done_ += n;
  if (!enabled_ && !callback_) return;
  const auto now = std::chrono::steady_clock::now();
  if (callback_) {
    std::unique_lock<std::mutex> lock(callback_mutex_, std::try_to_lock);
    if (lock.owns_lock() && !reported_final_ && now - last_report_ >= kInterval) {
      last_report_ = now;
      report();
    }
  }
  if (!enabled_) return;
  std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
  if (!lock.owns_lock() || finished_) return;
  if (now - last_draw_ < kInterval) return;
  last_draw_ = now;
  draw(false);
}

void Progress::finish() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (finished_) return;
    finished_ = true;
    if (enabled_) draw(true);
  }
  if (callback_) {
    std::lock_guard<std::mutex> lock(callback_mutex_);
    reported_final_ = true;
    report();
  }
}

void Progress::report() { (*callback_)(label_, std::min(done_.load(), total_), total_); }

void Progress::draw(bool final_line) {
  const std::size_t done = std::min(done_.load(), total_);
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const double rate = elapsed > 0 ? done / elapsed : 0.0;
  const double frac = total_ ? static_cast<double>(done) / total_ : 1.0;
  const int width = 30;
  const int filled = static_cast<int>(std::round(frac * width));
  std::string bar(filled, '#');
  bar += std::string(width - filled, '.');
  const double left = rate > 0 ? (total_ - done) / rate : 0.0;
  std::fprintf(stderr, "\r%s [%s] %zu/%zu %.1f/s %s %.0fs ", label_.c_str(), bar.c_str(), done,
               total_, rate, final_line ? "took" : "left", final_line ? elapsed : left);
  if (final_line) std::fputc('\n', stderr);
  std::fflush(stderr);
}

}  // namespace sonar3d
