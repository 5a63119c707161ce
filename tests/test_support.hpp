#pragma once
// Helpers shared by the GoogleTest suites.
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <string>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/sonar_spec.hpp"

namespace sonar3d::test {

// A fresh, empty directory for the running test: unique per suite, test and `name`, so that
// ctest -j can run the test executables side by side.
inline std::filesystem::path temp_dir(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::filesystem::path p =
      std::filesystem::temp_directory_path() /
      ("sonar3d_test_" + std::string(info ? info->test_suite_name() : "x") + "_" + name);
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p;
}

// A small sonar for dataset tests: 16 beams over 0.5 rad, 40 range bins over 0.5–2.5 m, 0.2 rad
// vertical aperture.
inline SonarSpec small_dataset_spec() {
  SonarSpec s;
  s.name = "small";
  s.set_uniform_bearings(0.5, 16);
  s.r_min = 0.5;
  s.r_max = 2.5;
  s.range_bins = 40;
  s.vertical_aperture_rad = 0.2;
  return s;
}

// Expects f() to throw sonar3d::Error whose message contains `needle`.
inline void expect_error(const std::function<void()>& f, const std::string& needle) {
  try {
    f();
    ADD_FAILURE() << "expected an error mentioning '" << needle << "'";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

}  // namespace sonar3d::test
