#include "sparseloop/io/mapped_pixels.h"

#include <cmath>
#include <limits>
#include <string>
#include <string_view>

#include <fmt/format.h>

#include "io/text_parsing.h"
#include "sparseloop/core/error.h"

namespace sparseloop {
namespace {

// A finite number that stays finite as a float (the type the detector takes): 1e39 became inf and
// failed later, as the keyframe's input, without the file or the line.
float ParseFiniteFloat(std::string_view token, const std::string& file, int line,
                       std::string_view what) {
  const double d = io_internal::ParseDouble(token, file, line, what);
  if (std::abs(d) > static_cast<double>(std::numeric_limits<float>::max())) {
    throw FileError(file, line,
                    fmt::format("a {} within float range (|x| <= {:g})", what,
                                static_cast<double>(std::numeric_limits<float>::max())),
                    std::string(token));
  }
  return static_cast<float>(d);
}

}  // namespace

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
    row.u = ParseFiniteFloat(t[0], name, line.number, "u");
    row.v = ParseFiniteFloat(t[1], name, line.number, "v");
    row.depth = ParseFiniteFloat(t[2], name, line.number, "depth");
    out.push_back(row);
  }
  return out;
}

}  // namespace sparseloop
