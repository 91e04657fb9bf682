#pragma once
// Ground-truth loop pairs as text: one "i j" pair of non-negative integer frame ids per line,
// '#' comment lines and blank lines allowed. The later frame is stored as LoopPair::query and the
// earlier as LoopPair::match whatever the column order (files differ); i == j is a FileError.
// Ids are returned as written (no 0/1-based conversion) and in file order.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

#include "sparseloop/core/loop_pair.h"

namespace sparseloop {

struct LoopPairReadOptions {
  // When set, every id must be below it (the frames of the trajectory the pairs belong to): a
  // pair naming a frame outside is a FileError with its line (pairs of another sequence, or
  // 1-based ids one past the end), instead of pairs that can never be matched.
  std::optional<int64_t> num_frames;
};

std::vector<LoopPair> ReadLoopPairs(const std::filesystem::path& path,
                                    const LoopPairReadOptions& options = {});

}  // namespace sparseloop
