// Fuzzes the g2o pose-graph reader (VERTEX_SE3:QUAT, EDGE_SE3:QUAT, VERTEX_SE2, EDGE_SE2).
#include <sstream>

#include "sparseloop/core/error.h"
#include "sparseloop/posegraph/g2o.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  try {
    sparseloop::ReadG2o(in, "fuzz.g2o");
  } catch (const sparseloop::Error&) {
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
