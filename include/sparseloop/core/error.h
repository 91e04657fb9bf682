#pragma once
#include <stdexcept>
#include <string>

namespace sparseloop {

// Base of every exception the library throws for bad *data* (as opposed to caller bugs, which
// throw std::invalid_argument via SL_CHECK).
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A file that is missing, unreadable or malformed. what() reads
//   "<file>:<line>: expected <expected>, got <got>"
// (":<line>" is omitted when line == 0, i.e. the problem concerns the whole file).
class FileError : public Error {
 public:
  FileError(std::string file, int line, std::string expected, std::string got = {});

  const std::string& file() const { return file_; }
  int line() const { return line_; }
  const std::string& expected() const { return expected_; }
  const std::string& got() const { return got_; }

 private:
  std::string file_;
  int line_ = 0;
  std::string expected_;
  std::string got_;
};

}  // namespace sparseloop
