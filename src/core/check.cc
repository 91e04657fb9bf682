#include "sparseloop/core/check.h"

#include "sparseloop/core/error.h"
#include "sparseloop/core/logging.h"

namespace sparseloop {
namespace internal {

void ThrowCheckFailure(const char* file, int line, const char* condition,
                       const std::string& message) {
  // Developers get the expression and the location; users only the readable message.
  Logger().debug("check failed: {} ({}:{}){}{}", condition, file, line, message.empty() ? "" : ": ",
                 message);
  throw CheckError(message.empty() ? fmt::format("check failed: {}", condition) : message,
                   condition, file, line);
}

}  // namespace internal

namespace {
std::string FormatFileError(const std::string& file, int line, const std::string& expected,
                            const std::string& got) {
  std::string msg = file;
  if (line > 0) msg += fmt::format(":{}", line);
  msg += ": expected " + expected;
  if (!got.empty()) msg += ", got " + got;
  return msg;
}
}  // namespace

FileError::FileError(std::string file, int line, std::string expected, std::string got)
    : Error(FormatFileError(file, line, expected, got)),
      file_(std::move(file)),
      line_(line),
      expected_(std::move(expected)),
      got_(std::move(got)) {}

}  // namespace sparseloop
