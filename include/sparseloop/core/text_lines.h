#pragma once
// Lines of a text file as editors write them, for every reader of the project's text formats.
#include <string_view>
#include <vector>

namespace sparseloop {

// The lines of `text`, without their ends: a line ends with "\n" (Unix), "\r\n" (Windows) or a
// lone "\r" (classic Mac OS, some exporters); index i is the line an editor numbers i + 1. A UTF-8
// byte order mark at the start (what some Windows editors write first) is not part of line 1.
// An end at the very end of the text opens no further line.
inline std::vector<std::string_view> SplitLines(std::string_view text) {
  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
  std::vector<std::string_view> lines;
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find_first_of("\r\n", start);
    if (end == std::string_view::npos) end = text.size();
    lines.push_back(text.substr(start, end - start));
    start = end + (text.substr(end, 2) == "\r\n" ? 2 : 1);
  }
  return lines;
}

}  // namespace sparseloop
