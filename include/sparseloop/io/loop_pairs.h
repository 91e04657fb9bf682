#pragma once
// Ground-truth loop pairs as text: one "i j" pair of non-negative integer frame ids per line,
// '#' comment lines and blank lines allowed. The later frame is stored as LoopPair::query and the
// earlier as LoopPair::match whatever the column order (files differ); i == j is a FileError.
// Ids are returned as written (no 0/1-based conversion) and in file order.
#include <filesystem>
#include <vector>

#include "sparseloop/core/loop_pair.h"

namespace sparseloop {

std::vector<LoopPair> ReadLoopPairs(const std::filesystem::path& path);

}  // namespace sparseloop
