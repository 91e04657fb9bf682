#pragma once
// One stored keyframe in one allocation: the bytes the detector keeps in memory and the map keeps
// in SQLite are the same (docs/FORMATS.md, "Packed keyframe record").
//
// Layout (little-endian, version 1), header 48 B then three arrays:
//   0  int64   id                    8  float64 timestamp (s)
//   16 float32 translation x, y, z   28 float32 scale        32 float32 focal_px
//   36 int16   rotation: the three smallest quaternion components x 32767 / sqrt(1/2) (the
//              largest one is positive and recomputed; its index is in flags bits 2-3)
//   42 uint16  K                     44 uint8 version         45 uint8 flags (bit 0 has_pose,
//              bit 1 has_depths, bits 2-3 index of the largest quaternion component)
//   46 int8    keypoint exponent e_k 47 int8 depth exponent e_d
//   48         K x 32 B ORB descriptors (8-byte aligned)
//   +          K x 2 int16 keypoints, normalised image x, y = code x 2^e_k
//   +          K IEEE half depths, depth = half x 2^e_d (only with has_depths; 0 = unknown)
// At K = 15 with depths a record is 48 + 480 + 60 + 30 = 618 B (+ 8 B for the owning pointer).
//
// Quantisation: translation, scale and focal to float, rotation to 2e-5 per component,
// keypoints to 2^e_k with e_k the smallest exponent where every code fits int16 (3e-5 for
// |x| < 1), depths to half precision (relative 5e-4). Packing is idempotent: the values a
// record decodes to pack to the same bytes, so memory -> map -> memory round trips exactly.
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "sparseloop/core/sim3.h"

namespace sparseloop {

// A 256-bit binary (ORB) descriptor as four 64-bit words.
using Descriptor256 = std::array<uint64_t, 4>;

// IEEE 754 binary16 conversion, round to nearest even (exposed for tests).
uint16_t FloatToHalf(float value);
float HalfToFloat(uint16_t half);

class PackedKeyframe {
 public:
  static constexpr uint8_t kVersion = 1;
  static constexpr size_t kHeaderBytes = 48;
  static constexpr int kMaxFeatures = 65535;

  // What a record holds, as plain values (the unpacked, quantised form when read back).
  struct Fields {
    int64_t id = 0;
    double timestamp = 0.0;
    bool has_pose = false;
    Sim3d world_from_cam;  // used only with has_pose (identity otherwise)
    float focal_px = 0.0f;
    std::vector<Descriptor256> descriptors;  // K
    std::vector<float> keypoints;            // 2K: x0 y0 x1 y1 ... (normalised)
    std::vector<float> depths;               // empty or K; <= 0 = unknown (stored as 0)
  };

  PackedKeyframe() = default;  // an empty record (K = 0, id 0, no pose)
  PackedKeyframe(const PackedKeyframe& other);
  PackedKeyframe& operator=(const PackedKeyframe& other);
  PackedKeyframe(PackedKeyframe&&) noexcept = default;
  PackedKeyframe& operator=(PackedKeyframe&&) noexcept = default;

  // Quantises and packs. Throws std::invalid_argument for inconsistent sizes, K > kMaxFeatures,
  // a non-finite value, a non-positive scale or a non-unit quaternion (1e-3).
  static PackedKeyframe Pack(const Fields& fields);
  // Reads bytes written by bytes(); throws std::invalid_argument (naming what is wrong) for a
  // wrong size, version or flag, an exponent outside Pack's range, a rotation code that is not a
  // unit quaternion, a negative depth or a non-finite value: what it accepts, Pack accepts again.
  static PackedKeyframe FromBytes(std::span<const uint8_t> bytes);
  Fields Unpack() const;

  std::span<const uint8_t> bytes() const;
  // Memory held: this object plus its one allocation.
  size_t Bytes() const { return sizeof(PackedKeyframe) + ByteSize(); }

  int64_t id() const;
  double timestamp() const;
  bool has_pose() const;
  bool has_depths() const;
  Sim3d world_from_cam() const;  // identity without a pose
  float focal_px() const;
  size_t size() const;  // K
  std::span<const Descriptor256> descriptors() const;
  float keypoint_x(size_t i) const;
  float keypoint_y(size_t i) const;
  float depth(size_t i) const;  // 0 without depths

 private:
  size_t ByteSize() const;
  const uint8_t* data() const { return reinterpret_cast<const uint8_t*>(words_.get()); }
  // 8-byte words so that the descriptors (at byte 48) are aligned for 64-bit reads.
  std::unique_ptr<uint64_t[]> words_;
};

}  // namespace sparseloop
