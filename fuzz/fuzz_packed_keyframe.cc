// Fuzzes the packed keyframe record (the bytes a map file stores per keyframe): arbitrary bytes
// must either be refused with std::invalid_argument or give a record whose values are finite and
// whose decoded values pack again without error, to a record that decodes to the same values.
#include <cmath>
#include <cstdlib>
#include <span>
#include <stdexcept>

#include "sparseloop/core/packed_keyframe.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using sparseloop::PackedKeyframe;
  PackedKeyframe record;
  try {
    record = PackedKeyframe::FromBytes(std::span<const uint8_t>(data, size));
  } catch (const std::invalid_argument&) {
    return 0;
  }
  const PackedKeyframe::Fields f = record.Unpack();
  for (float v : f.keypoints)
    if (!std::isfinite(v)) std::abort();
  for (float v : f.depths)
    if (!std::isfinite(v)) std::abort();
  if (f.has_pose && std::abs(f.world_from_cam.rotation.norm() - 1.0) > 1e-6) std::abort();
  // Decoded values always pack (the ranges fit) and are a fixed point after one pass.
  const PackedKeyframe again = PackedKeyframe::Pack(f);
  const PackedKeyframe::Fields g = again.Unpack();
  if (g.keypoints != f.keypoints || g.depths != f.depths || g.descriptors != f.descriptors)
    std::abort();
  return 0;
}
