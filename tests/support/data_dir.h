#pragma once
// Where the real data is: ../shared/data (configured as SPARSELOOP_DATA_DIR), or $SPARSELOOP_DATA
// when set. Shared by the tests (test_util.h) and the accuracy programs in bench/ (no GoogleTest).
#include <cstdlib>
#include <filesystem>

namespace sparseloop::test {

inline std::filesystem::path DataDir() {
  if (const char* env = std::getenv("SPARSELOOP_DATA")) return env;
  return SPARSELOOP_DATA_DIR;
}

}  // namespace sparseloop::test
