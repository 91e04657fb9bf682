// Common gtest main: seeds every RNG the tests use through SeededRng() (tests/test_util.h), and
// silences the library logger below warnings so test output stays readable.
#include <gtest/gtest.h>

#include "sparseloop/core/logging.h"

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  sparseloop::Logger().set_level(spdlog::level::warn);
  return RUN_ALL_TESTS();
}
