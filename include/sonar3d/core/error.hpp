#pragma once
// Errors carry what was wrong, where (file, line, key, frame) and what to do. The CLI prints
// what() as one line and exits non-zero.
#include <stdexcept>
#include <string>

namespace sonar3d {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

// A long operation stopped by a signal (SIGINT, SIGTERM) after cleaning up what it started; the
// CLI prints what() and exits with 128 + signal(), as a shell does for a killed command.
class Interrupted : public Error {
 public:
  Interrupted(const std::string& what, int signal) : Error(what), signal_(signal) {}
  int signal() const { return signal_; }

 private:
  int signal_;
};

// Throws Error(message) when cond is false.
inline void require(bool cond, const std::string& message) {
  if (!cond) throw Error(message);
}

// `text` made safe to quote in a one-line error: control and non-ASCII bytes become '?', and
// anything beyond `max` characters is cut with "...". Used wherever file content is echoed.
std::string printable(const std::string& text, std::size_t max = 60);

// Checks that a configuration value is finite and strictly positive; names the parameter.
void require_positive(double value, const char* name, const char* unit = "");
// Checks that a configuration value is finite and >= 0.
void require_non_negative(double value, const char* name, const char* unit = "");

}  // namespace sonar3d
