// The configured paths of data_dir.h: the only file compiled with them (see there).
#include "data_dir.h"

namespace sparseloop::test {

std::filesystem::path ConfiguredDataDir() { return SPARSELOOP_DATA_DIR; }
std::filesystem::path ConfiguredSourceDir() { return SPARSELOOP_SOURCE_DIR; }
std::filesystem::path ConfiguredBinaryDir() { return SPARSELOOP_BINARY_DIR; }
std::filesystem::path ConfiguredCliPath() {
#ifdef SPARSELOOP_CLI
  return SPARSELOOP_CLI;
#else
  return {};
#endif
}

}  // namespace sparseloop::test
