#include "sparseloop/io/loop_pairs.h"

#include <algorithm>

#include <fmt/format.h>

#include "io/text_parsing.h"
#include "sparseloop/core/error.h"

namespace sparseloop {

std::vector<LoopPair> ReadLoopPairs(const std::filesystem::path& path,
                                    const LoopPairReadOptions& options) {
  const io_internal::TextFile file(path);
  const auto& name = file.name();
  std::vector<LoopPair> pairs;
  for (const auto& line : file.DataLines()) {
    const auto t = io_internal::SplitWhitespace(line.text);
    if (t.size() != 2) {
      throw FileError(name, line.number, "2 columns (i j)", fmt::format("{} columns", t.size()));
    }
    const int64_t i = io_internal::ParseInt64(t[0], name, line.number, "frame id i");
    const int64_t j = io_internal::ParseInt64(t[1], name, line.number, "frame id j");
    if (i < 0 || j < 0) {
      throw FileError(name, line.number, "non-negative frame ids", fmt::format("{} {}", i, j));
    }
    if (i == j) {
      throw FileError(name, line.number, "two different frame ids", fmt::format("{} {}", i, j));
    }
    if (options.num_frames && std::max(i, j) >= *options.num_frames) {
      throw FileError(
          name, line.number,
          fmt::format("frame ids 0..{} (the trajectory's frames)", *options.num_frames - 1),
          fmt::format("{} {}", i, j));
    }
    pairs.push_back(LoopPair{std::max(i, j), std::min(i, j)});
  }
  return pairs;
}

}  // namespace sparseloop
