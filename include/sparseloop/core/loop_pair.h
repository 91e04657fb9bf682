#pragma once
#include <cstdint>

namespace sparseloop {

// A loop between two frames (or keyframes) of one trajectory: `query` is the later frame,
// `match` the earlier one it revisits. Ids are 0-based frame indices unless stated otherwise.
struct LoopPair {
  int64_t query = 0;
  int64_t match = 0;
  friend bool operator==(const LoopPair&, const LoopPair&) = default;
};

}  // namespace sparseloop
