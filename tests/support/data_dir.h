#pragma once
// Where the real data is: ../shared/data (configured as SPARSELOOP_DATA_DIR), or $SPARSELOOP_DATA
// when set. Shared by the tests (test_util.h) and the accuracy programs in bench/ (no GoogleTest).
// The configured paths are compiled into one file (data_dir.cc), so that no other file's compile
// command holds an absolute path: a clone at another path reuses the compiler cache.
#include <cstdlib>
#include <filesystem>

namespace sparseloop::test {

// The configured SPARSELOOP_DATA_DIR (data_dir.cc).
std::filesystem::path ConfiguredDataDir();
// The configured source tree, build tree and CLI binary (data_dir.cc; empty when not configured:
// the CLI path outside a build with the CLI).
std::filesystem::path ConfiguredSourceDir();
std::filesystem::path ConfiguredBinaryDir();
std::filesystem::path ConfiguredCliPath();

inline std::filesystem::path DataDir() {
  if (const char* env = std::getenv("SPARSELOOP_DATA")) return env;
  return ConfiguredDataDir();
}

}  // namespace sparseloop::test
