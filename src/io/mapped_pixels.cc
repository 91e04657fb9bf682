#include "sparseloop/io/mapped_pixels.h"

#include <fmt/format.h>

#include "io/text_parsing.h"
#include "sparseloop/core/error.h"

namespace sparseloop {

std::vector<MappedPixelRow> ReadMappedPixelRows(const std::filesystem::path& path) {
  const io_internal::TextFile file(path);
  const auto& name = file.name();
  std::vector<MappedPixelRow> out;
  for (const auto& line : file.DataLines()) {
    const auto t = io_internal::SplitWhitespace(line.text);
    if (t.size() != 3) {
      throw FileError(name, line.number, "3 numbers 'u v depth'",
                      fmt::format("{} columns", t.size()));
    }
    MappedPixelRow row;
    row.u = static_cast<float>(io_internal::ParseDouble(t[0], name, line.number, "u"));
    row.v = static_cast<float>(io_internal::ParseDouble(t[1], name, line.number, "v"));
    row.depth = static_cast<float>(io_internal::ParseDouble(t[2], name, line.number, "depth"));
    out.push_back(row);
  }
  return out;
}

}  // namespace sparseloop
