#pragma once
// Shared by the libFuzzer targets: a private scratch directory per process, file writing, and
// the rule every target checks — a parser may only fail with sonar3d::Error. Any other exception
// (std::bad_alloc, std::length_error, YAML::Exception, nlohmann::json::exception ...) is a bug:
// it would reach the user without naming the file, so the target aborts and libFuzzer reports it.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

#include "sonar3d/core/error.hpp"

namespace sonar3d::fuzz {

inline const std::filesystem::path& scratch() {
  static const std::filesystem::path dir = [] {
    std::string tmpl = (std::filesystem::temp_directory_path() / "sonar3d_fuzz_XXXXXX").string();
    if (!mkdtemp(tmpl.data())) std::abort();
    return std::filesystem::path(tmpl);
  }();
  return dir;
}

inline void write_file(const std::filesystem::path& p, std::string_view bytes) {
  std::filesystem::create_directories(p.parent_path());
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// Splits the input at lines "--8<--" into at most `n` parts (missing parts are empty).
inline std::vector<std::string_view> split(const uint8_t* data, size_t size, size_t n) {
  std::string_view s(reinterpret_cast<const char*>(data), size);
  std::vector<std::string_view> parts;
  const std::string_view sep = "\n--8<--\n";
  while (parts.size() + 1 < n) {
    const size_t at = s.find(sep);
    if (at == std::string_view::npos) break;
    parts.push_back(s.substr(0, at));
    s.remove_prefix(at + sep.size());
  }
  parts.push_back(s);
  parts.resize(n);
  return parts;
}

// Runs f(); sonar3d::Error is the expected failure, anything else aborts with the message.
template <class F>
void run(F&& f) {
  try {
    f();
  } catch (const sonar3d::Error&) {
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fuzz: non-sonar3d exception escaped: %s\n", e.what());
    std::abort();
  } catch (...) {
    std::fprintf(stderr, "fuzz: unknown exception escaped\n");
    std::abort();
  }
}

}  // namespace sonar3d::fuzz
