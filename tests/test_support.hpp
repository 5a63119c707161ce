#pragma once
// Helpers shared by the GoogleTest suites.
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <string>

#include "sonar3d/core/error.hpp"

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
