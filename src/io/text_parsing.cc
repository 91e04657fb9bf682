#include "io/text_parsing.h"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <system_error>

#include <fmt/format.h>

#include "sparseloop/core/error.h"
#include "sparseloop/core/text_lines.h"

namespace sparseloop::io_internal {

TextFile::TextFile(const std::filesystem::path& path) : name_(path.string()) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    // A loop of symbolic links or a folder without search permission, not just a missing file.
    throw FileError(name_, 0, "an existing file",
                    ec && ec != std::errc::no_such_file_or_directory ? ec.message() : "none");
  }
  if (std::filesystem::is_directory(path, ec)) {
    throw FileError(name_, 0, "a regular file", "a directory");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FileError(name_, 0, "a readable file", std::strerror(errno));
  // Read once, in chunks: a FIFO or /dev/stdin is read as a file is, and a stream that does not
  // end stops at the bound instead of filling the memory.
  std::vector<char> chunk(size_t{1} << 16);
  while (in.read(chunk.data(), static_cast<std::streamsize>(chunk.size())) || in.gcount() > 0) {
    content_.append(chunk.data(), static_cast<size_t>(in.gcount()));
    if (content_.size() > kMaxTextFileBytes) {
      throw FileError(name_, 0, fmt::format("a text file of at most {} bytes", kMaxTextFileBytes),
                      "more (a stream that does not end?)");
    }
  }
  if (in.bad()) throw FileError(name_, 0, "a readable file", "read error");
  int number = 1;
  for (const std::string_view line : SplitLines(content_)) lines_.push_back({number++, line});
}

std::vector<TextLine> TextFile::DataLines() const {
  std::vector<TextLine> out;
  for (const auto& l : lines_) {
    if (!IsBlankOrComment(l.text)) out.push_back(l);
  }
  return out;
}

std::string_view Trim(std::string_view s) {
  const char* ws = " \t\r\n\v\f";
  const size_t b = s.find_first_not_of(ws);
  if (b == std::string_view::npos) return {};
  const size_t e = s.find_last_not_of(ws);
  return s.substr(b, e - b + 1);
}

bool IsBlankOrComment(std::string_view line) {
  const std::string_view t = Trim(line);
  return t.empty() || t.front() == '#';
}

std::vector<std::string_view> SplitWhitespace(std::string_view line) {
  std::vector<std::string_view> out;
  size_t i = 0;
  auto is_ws = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; };
  while (i < line.size()) {
    while (i < line.size() && is_ws(line[i])) ++i;
    if (i < line.size() && line[i] == '#') break;  // a trailing comment
    size_t j = i;
    while (j < line.size() && !is_ws(line[j])) ++j;
    if (j > i) out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

std::vector<std::string_view> SplitComma(std::string_view line) {
  std::vector<std::string_view> out;
  size_t start = 0;
  while (true) {
    const size_t end = line.find(',', start);
    if (end == std::string_view::npos) {
      out.push_back(Trim(line.substr(start)));
      break;
    }
    out.push_back(Trim(line.substr(start, end - start)));
    start = end + 1;
  }
  return out;
}

std::string Quote(std::string_view token) {
  constexpr size_t kMax = 40;
  if (token.size() > kMax) return fmt::format("'{}...'", token.substr(0, kMax));
  return fmt::format("'{}'", token);
}

namespace {
bool ParseDoubleRaw(std::string_view token, double* value) {
  if (token.empty()) return false;
  if (token.front() == '+') token.remove_prefix(1);
  if (token.empty() || token.front() == '+') return false;
  const char* end = token.data() + token.size();
  auto [ptr, ec] = std::from_chars(token.data(), end, *value);
  if (ec == std::errc::result_out_of_range) {
    *value = HUGE_VAL;  // reported as non-finite by the caller
    return ptr == end;
  }
  return ec == std::errc() && ptr == end;
}
}  // namespace

bool LooksLikeNumber(std::string_view token) {
  double v = 0.0;
  return ParseDoubleRaw(token, &v);
}

double ParseDouble(std::string_view token, const std::string& file, int line,
                   std::string_view what) {
  double v = 0.0;
  if (!ParseDoubleRaw(token, &v) || !std::isfinite(v)) {
    throw FileError(file, line, fmt::format("a finite number for {}", what), Quote(token));
  }
  return v;
}

bool LooksLikeInteger(std::string_view token) {
  if (!token.empty() && (token.front() == '-' || token.front() == '+')) token.remove_prefix(1);
  if (token.empty()) return false;
  for (char c : token) {
    if (c < '0' || c > '9') return false;
  }
  return true;
}

int64_t ParseInt64(std::string_view token, const std::string& file, int line,
                   std::string_view what) {
  std::string_view digits = token;
  if (!digits.empty() && digits.front() == '+') digits.remove_prefix(1);
  int64_t v = 0;
  const char* end = digits.data() + digits.size();
  auto [ptr, ec] = std::from_chars(digits.data(), end, v);
  if (!LooksLikeInteger(token) || ec != std::errc() || ptr != end) {
    throw FileError(file, line, fmt::format("an integer for {}", what), Quote(token));
  }
  return v;
}

}  // namespace sparseloop::io_internal
