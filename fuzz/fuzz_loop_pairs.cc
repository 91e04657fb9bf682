// Fuzzes the loop-pair list reader ("i j" per line).
#include "fuzz_util.h"
#include "sparseloop/core/error.h"
#include "sparseloop/io/loop_pairs.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = sparseloop::fuzz::WriteInput(data, size, "pairs.txt");
  try {
    sparseloop::ReadLoopPairs(path);
  } catch (const sparseloop::Error&) {
  }
  return 0;
}
