#include "sparseloop/io/raw_scale.h"

#include <fmt/format.h>

#include "io/text_parsing.h"
#include "sparseloop/core/error.h"

namespace sparseloop {

std::vector<double> ReadRawScale(const std::filesystem::path& path) {
  const io_internal::TextFile file(path);
  std::vector<double> out;
  for (const auto& line : file.DataLines()) {
    const auto t = io_internal::SplitWhitespace(line.text);
    if (t.size() != 1) {
      throw FileError(file.name(), line.number, "one number per line (the raw scale)",
                      fmt::format("{} columns", t.size()));
    }
    const double s = io_internal::ParseDouble(t[0], file.name(), line.number, "the raw scale");
    if (!(s > 0)) {
      throw FileError(file.name(), line.number, "a positive raw scale", io_internal::Quote(t[0]));
    }
    out.push_back(s);
  }
  return out;
}

}  // namespace sparseloop
