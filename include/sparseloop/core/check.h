#pragma once
// One error policy for the whole library (see docs/ARCHITECTURE.md, "Errors"):
//  - a broken precondition (a caller bug, an invalid option) throws std::invalid_argument through
//    SL_CHECK / SL_CHECK_MSG;
//  - an expected failure (no loop, too few inliers) is a status in a result struct;
//  - a malformed file throws sparseloop::FileError (core/error.h) naming file, line and
//  expectation.
// The library never aborts and never writes to stdout.
//
// The exception's what() is the readable message only ("max_dt must be >= 0 s, got -1"), which
// is what reaches users; a check without a message reads "check failed: <condition>". The C++
// condition and the source location are for developers: CheckError::condition() / file() /
// line(), and a debug-level log line (Logger(), stderr) when the check fails.
#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace sparseloop {

class CheckError : public std::invalid_argument {
 public:
  CheckError(const std::string& message, const char* condition, const char* file, int line)
      : std::invalid_argument(message), condition_(condition), file_(file), line_(line) {}
  const char* condition() const { return condition_; }
  const char* file() const { return file_; }
  int line() const { return line_; }

 private:
  const char* condition_;  // string literals from the macros: static storage
  const char* file_;
  int line_;
};

namespace internal {
[[noreturn]] void ThrowCheckFailure(const char* file, int line, const char* condition,
                                    const std::string& message);
}  // namespace internal
}  // namespace sparseloop

#define SL_CHECK(condition)                                                          \
  do {                                                                               \
    if (!(condition)) {                                                              \
      ::sparseloop::internal::ThrowCheckFailure(__FILE__, __LINE__, #condition, ""); \
    }                                                                                \
  } while (false)

// SL_CHECK_MSG(x > 0, "x must be positive, got {}", x)
#define SL_CHECK_MSG(condition, ...)                                            \
  do {                                                                          \
    if (!(condition)) {                                                         \
      ::sparseloop::internal::ThrowCheckFailure(__FILE__, __LINE__, #condition, \
                                                ::fmt::format(__VA_ARGS__));    \
    }                                                                           \
  } while (false)
