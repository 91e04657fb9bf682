#pragma once
// One error policy for the whole library (see docs/ARCHITECTURE.md, "Errors"):
//  - a broken precondition (a caller bug, an invalid option) throws std::invalid_argument through
//    SL_CHECK / SL_CHECK_MSG;
//  - an expected failure (no loop, too few inliers) is a status in a result struct;
//  - a malformed file throws sparseloop::FileError (core/error.h) naming file, line and expectation.
// The library never aborts and never writes to stdout.
#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace sparseloop::internal {
[[noreturn]] void ThrowCheckFailure(const char* file, int line, const char* condition,
                                    const std::string& message);
}  // namespace sparseloop::internal

#define SL_CHECK(condition)                                                          \
  do {                                                                               \
    if (!(condition)) {                                                              \
      ::sparseloop::internal::ThrowCheckFailure(__FILE__, __LINE__, #condition, ""); \
    }                                                                                \
  } while (false)

// SL_CHECK_MSG(x > 0, "x must be positive, got {}", x)
#define SL_CHECK_MSG(condition, ...)                                               \
  do {                                                                             \
    if (!(condition)) {                                                            \
      ::sparseloop::internal::ThrowCheckFailure(__FILE__, __LINE__, #condition,    \
                                                ::fmt::format(__VA_ARGS__));       \
    }                                                                              \
  } while (false)
