#pragma once
// Test helpers: real-data location, skip/fail policy, temp dirs, seeded RNG.
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "data_dir.h"  // tests/support: DataDir()

namespace sparseloop::test {

inline bool InCi() {
  const char* ci = std::getenv("CI");
  return ci != nullptr && std::string(ci) == "true";
}

inline std::filesystem::path SourceDir() { return ConfiguredSourceDir(); }

// A fresh, empty directory for this test (`suffix` gives a second, independent one).
// Every call empties it: call once per test and keep the path.
inline std::filesystem::path TempDir(const std::string& suffix = "") {
  const auto* info = testing::UnitTest::GetInstance()->current_test_info();
  std::filesystem::path root = std::getenv("SPARSELOOP_TEST_TMP")
                                   ? std::getenv("SPARSELOOP_TEST_TMP")
                                   : std::filesystem::temp_directory_path() / "sparseloop_tests";
  auto dir = root / (std::string(info->test_suite_name()) + "." + info->name() + suffix);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

inline std::mt19937_64 SeededRng(uint64_t salt = 0) { return std::mt19937_64(20261122 + salt); }

}  // namespace sparseloop::test

// Skips the test (with a clear message) when a real-data folder is absent; fails instead when
// CI=true, because CI must exercise the real data.
#define SL_REQUIRE_DATA(relative)                                                         \
  do {                                                                                    \
    const auto sl_data_path = ::sparseloop::test::DataDir() / (relative);                 \
    if (!std::filesystem::exists(sl_data_path)) {                                         \
      if (::sparseloop::test::InCi()) {                                                   \
        FAIL() << "real data missing in CI: " << sl_data_path                             \
               << " (set SPARSELOOP_DATA or place ../shared/data next to the repo)";      \
      }                                                                                   \
      GTEST_SKIP() << "real data not found at " << sl_data_path                           \
                   << "; set SPARSELOOP_DATA to the shared data folder to run this test"; \
    }                                                                                     \
  } while (false)
