#pragma once
// Private helpers shared by the io readers: line splitting and strict number parsing that throw
// FileError with the file name and the 1-based line number.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace sparseloop::io_internal {

struct TextLine {
  int number = 0;         // 1-based line number in the file
  std::string_view text;  // without the trailing '\r' / '\n'
};

// Largest text file read (1 GiB): beyond any trajectory or list the readers take (100,000 TUM poses
// are about 10 MB).
inline constexpr size_t kMaxTextFileBytes = size_t{1} << 30;

// A whole text file in memory with its lines, read once (a FIFO or /dev/stdin works). Throws
// FileError(path, 0, ...) when the file is missing, a directory, unreadable or larger than
// kMaxTextFileBytes.
class TextFile {
 public:
  explicit TextFile(const std::filesystem::path& path);
  const std::string& name() const { return name_; }
  const std::vector<TextLine>& lines() const { return lines_; }
  // Lines that are neither blank nor '#' comments (leading whitespace ignored).
  std::vector<TextLine> DataLines() const;

 private:
  std::string name_;
  std::string content_;
  std::vector<TextLine> lines_;
};

std::string_view Trim(std::string_view s);
bool IsBlankOrComment(std::string_view line);
// The whitespace-separated tokens of a line, up to a token that starts with '#': a trailing
// comment ("1 0 0 ... 1  # start") ends the data, as a '#' line is a comment. A '#' inside a token
// ("1#2") is part of it.
std::vector<std::string_view> SplitWhitespace(std::string_view line);
// Splits on ',' and trims each field.
std::vector<std::string_view> SplitComma(std::string_view line);
// Quotes a token for an error message, shortened if long.
std::string Quote(std::string_view token);

// Strict: the whole token must be a number; NaN and Inf are rejected. `what` names the field in the
// FileError ("finite number for <what>").
double ParseDouble(std::string_view token, const std::string& file, int line,
                   std::string_view what);
// Strict integer (optional leading '-' or '+', digits only).
int64_t ParseInt64(std::string_view token, const std::string& file, int line,
                   std::string_view what);
// True when the token is an integer literal (digits with an optional sign; no '.', no exponent).
bool LooksLikeInteger(std::string_view token);
// True when the token parses completely as a double (finite or not).
bool LooksLikeNumber(std::string_view token);

}  // namespace sparseloop::io_internal
