#include "sparseloop/core/packed_keyframe.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include "sparseloop/core/check.h"

namespace sparseloop {
namespace {

static_assert(std::endian::native == std::endian::little, "the packed record is little-endian");
static_assert(sizeof(Descriptor256) == 32);

// Byte offsets of the header fields (see the layout in the header file).
constexpr size_t kOffId = 0;
constexpr size_t kOffTimestamp = 8;
constexpr size_t kOffTranslation = 16;
constexpr size_t kOffScale = 28;
constexpr size_t kOffFocal = 32;
constexpr size_t kOffRotation = 36;
constexpr size_t kOffK = 42;
constexpr size_t kOffVersion = 44;
constexpr size_t kOffFlags = 45;
constexpr size_t kOffKeypointExp = 46;
constexpr size_t kOffDepthExp = 47;

constexpr uint8_t kFlagPose = 1;
constexpr uint8_t kFlagDepths = 2;
constexpr int kRotationIndexShift = 2;

constexpr int kMinExponent = -100;
constexpr int kMaxExponent = 120;
// Rotation codes: the three smallest components of a unit quaternion lie in [-sqrt(1/2),
// sqrt(1/2)].
const double kRotationStep = std::sqrt(0.5) / 32767.0;

// The one zeroed header an empty record reads from.
constexpr uint8_t kEmptyHeader[PackedKeyframe::kHeaderBytes] = {};

template <typename T>
T Load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}
template <typename T>
void Store(uint8_t* p, T v) {
  std::memcpy(p, &v, sizeof(T));
}

size_t RecordBytes(size_t k, bool depths) {
  return PackedKeyframe::kHeaderBytes + k * 32 + k * 4 + (depths ? k * 2 : 0);
}

struct RotationCode {
  int largest = 3;
  std::array<int16_t, 3> codes{};
};

Eigen::Quaterniond DecodeRotation(const RotationCode& c) {
  double q[4];
  double sum = 0.0;
  for (int i = 0, j = 0; i < 4; ++i) {
    if (i == c.largest) continue;
    q[i] = c.codes[j++] * kRotationStep;
    sum += q[i] * q[i];
  }
  q[c.largest] = std::sqrt(std::max(0.0, 1.0 - sum));
  return Eigen::Quaterniond(q[3], q[0], q[1], q[2]);  // w, x, y, z
}

int LargestIndex(const double q[4]) {
  int l = 0;
  for (int i = 1; i < 4; ++i)
    if (std::abs(q[i]) > std::abs(q[l])) l = i;
  return l;
}

// Smallest-three code whose decoded quaternion encodes to itself (the largest component's index
// is re-checked on the decoded value, so a near tie settles on one index).
RotationCode EncodeRotation(const Eigen::Quaterniond& rotation) {
  double q[4] = {rotation.x(), rotation.y(), rotation.z(), rotation.w()};
  RotationCode c;
  for (int iteration = 0; iteration < 4; ++iteration) {
    c.largest = LargestIndex(q);
    const double sign = q[c.largest] < 0 ? -1.0 : 1.0;
    for (int i = 0, j = 0; i < 4; ++i) {
      if (i == c.largest) continue;
      const double code = std::clamp(std::round(sign * q[i] / kRotationStep), -32767.0, 32767.0);
      c.codes[j++] = static_cast<int16_t>(code);
    }
    const Eigen::Quaterniond d = DecodeRotation(c);
    const double dq[4] = {d.x(), d.y(), d.z(), d.w()};
    if (LargestIndex(dq) == c.largest) break;
    std::copy(dq, dq + 4, q);
  }
  return c;
}

// Smallest exponent e >= kMinExponent at which every value / 2^e, rounded, fits `fits`. The
// search starts below the smallest possible e, so the result is minimal: values decoded from the
// codes give the same e (idempotent packing).
template <typename Fits>
int SmallestExponent(float max_abs, Fits fits, const char* what) {
  int e = kMinExponent;
  if (max_abs > 0) {
    int p = 0;
    std::frexp(max_abs, &p);
    e = std::max(kMinExponent, p - 18);
  }
  for (; e <= kMaxExponent; ++e)
    if (fits(e)) return e;
  SL_CHECK_MSG(false, "packed keyframe: {} too large to quantise (max {})", what, max_abs);
  return 0;
}

}  // namespace

uint16_t FloatToHalf(float value) {
  const uint32_t f = std::bit_cast<uint32_t>(value);
  const uint32_t sign = (f >> 16) & 0x8000u;
  const uint32_t abs = f & 0x7fffffffu;
  if (abs >= 0x7f800000u)  // inf or NaN
    return static_cast<uint16_t>(sign | 0x7c00u | (abs > 0x7f800000u ? 0x200u : 0u));
  if (abs >= 0x477ff000u) return static_cast<uint16_t>(sign | 0x7c00u);  // rounds to >= 65520
  if (abs < 0x38800000u) {  // below the smallest normal half (2^-14): subnormal or zero
    if (abs < 0x33000000u) return static_cast<uint16_t>(sign);  // < 2^-25 rounds to 0
    const uint32_t exponent = abs >> 23;
    const uint32_t mantissa = (abs & 0x7fffffu) | 0x800000u;
    const uint32_t shift = 126 - exponent;  // 14..24
    uint32_t h = mantissa >> shift;
    const uint32_t rest = mantissa & ((1u << shift) - 1);
    const uint32_t half = 1u << (shift - 1);
    if (rest > half || (rest == half && (h & 1u))) ++h;
    return static_cast<uint16_t>(sign | h);
  }
  // Normal: rebias the exponent (127 -> 15) and round the 23-bit mantissa to 10 bits.
  uint32_t h = ((abs - 0x38000000u) >> 13);
  const uint32_t rest = abs & 0x1fffu;
  if (rest > 0x1000u || (rest == 0x1000u && (h & 1u))) ++h;  // may carry into the exponent
  return static_cast<uint16_t>(sign | h);
}

float HalfToFloat(uint16_t half) {
  const uint32_t sign = static_cast<uint32_t>(half & 0x8000u) << 16;
  const uint32_t exponent = (half >> 10) & 0x1fu;
  const uint32_t mantissa = half & 0x3ffu;
  if (exponent == 0) {  // zero or subnormal: mantissa x 2^-24
    const float v = std::ldexp(static_cast<float>(mantissa), -24);
    return sign ? -v : v;
  }
  if (exponent == 31) return std::bit_cast<float>(sign | 0x7f800000u | (mantissa << 13));
  return std::bit_cast<float>(sign | ((exponent + 112) << 23) | (mantissa << 13));
}

PackedKeyframe::PackedKeyframe(const PackedKeyframe& other) { *this = other; }

PackedKeyframe& PackedKeyframe::operator=(const PackedKeyframe& other) {
  if (this == &other) return *this;
  if (!other.words_) {
    words_.reset();
    return *this;
  }
  const size_t words = (other.ByteSize() + 7) / 8;
  std::unique_ptr<uint64_t[]> copy(new uint64_t[words]);
  std::memcpy(copy.get(), other.words_.get(), words * 8);
  words_ = std::move(copy);
  return *this;
}

PackedKeyframe PackedKeyframe::Pack(const Fields& f) {
  const size_t k = f.descriptors.size();
  SL_CHECK_MSG(k <= static_cast<size_t>(kMaxFeatures),
               "packed keyframe {}: at most {} features, got {}", f.id, kMaxFeatures, k);
  SL_CHECK_MSG(f.keypoints.size() == 2 * k,
               "packed keyframe {}: expected {} keypoint coordinates (2 per descriptor), got {}",
               f.id, 2 * k, f.keypoints.size());
  SL_CHECK_MSG(f.depths.empty() || f.depths.size() == k,
               "packed keyframe {}: expected 0 or {} depths, got {}", f.id, k, f.depths.size());
  SL_CHECK_MSG(std::isfinite(f.timestamp) && std::isfinite(f.focal_px),
               "packed keyframe {}: timestamp and focal length must be finite", f.id);
  const bool depths = !f.depths.empty();

  float max_kp = 0.0f;
  for (float v : f.keypoints) {
    SL_CHECK_MSG(std::isfinite(v), "packed keyframe {}: keypoint coordinate is not finite", f.id);
    max_kp = std::max(max_kp, std::abs(v));
  }
  const int e_k = SmallestExponent(
      max_kp,
      [&](int e) {
        for (float v : f.keypoints)
          if (std::abs(std::round(std::ldexp(v, -e))) > 32767.0f) return false;
        return true;
      },
      "keypoint coordinates");
  float max_depth = 0.0f;
  for (float d : f.depths) {
    SL_CHECK_MSG(!std::isnan(d) && !std::isinf(d), "packed keyframe {}: depth is not finite", f.id);
    if (d > 0) max_depth = std::max(max_depth, d);
  }
  const int e_d = SmallestExponent(
      max_depth,
      [&](int e) { return HalfToFloat(FloatToHalf(std::ldexp(max_depth, -e))) < 32768.0f; },
      "depths");

  RotationCode rotation;
  Eigen::Vector3f translation = Eigen::Vector3f::Zero();
  float scale = 1.0f;
  if (f.has_pose) {
    const Sim3d& p = f.world_from_cam;
    SL_CHECK_MSG(p.translation.allFinite() && p.rotation.coeffs().allFinite() &&
                     std::isfinite(p.scale) && p.scale > 0,
                 "packed keyframe {}: pose is not finite or its scale is not positive", f.id);
    SL_CHECK_MSG(std::abs(p.rotation.norm() - 1.0) < 1e-3,
                 "packed keyframe {}: non-unit quaternion (norm {})", f.id, p.rotation.norm());
    translation = p.translation.cast<float>();
    scale = static_cast<float>(p.scale);
    SL_CHECK_MSG(translation.allFinite() && std::isfinite(scale) && scale > 0,
                 "packed keyframe {}: pose outside the float range", f.id);
    rotation = EncodeRotation(p.rotation.normalized());
  }

  const size_t bytes = RecordBytes(k, depths);
  PackedKeyframe out;
  out.words_.reset(new uint64_t[(bytes + 7) / 8]());
  uint8_t* d = reinterpret_cast<uint8_t*>(out.words_.get());
  Store<int64_t>(d + kOffId, f.id);
  Store<double>(d + kOffTimestamp, f.timestamp);
  for (int i = 0; i < 3; ++i) Store<float>(d + kOffTranslation + 4 * i, translation[i]);
  Store<float>(d + kOffScale, scale);
  Store<float>(d + kOffFocal, f.focal_px);
  for (int i = 0; i < 3; ++i) Store<int16_t>(d + kOffRotation + 2 * i, rotation.codes[i]);
  Store<uint16_t>(d + kOffK, static_cast<uint16_t>(k));
  d[kOffVersion] = kVersion;
  d[kOffFlags] = static_cast<uint8_t>((f.has_pose ? kFlagPose : 0) | (depths ? kFlagDepths : 0) |
                                      (rotation.largest << kRotationIndexShift));
  d[kOffKeypointExp] = static_cast<uint8_t>(static_cast<int8_t>(e_k));
  d[kOffDepthExp] = static_cast<uint8_t>(static_cast<int8_t>(e_d));
  uint8_t* p = d + kHeaderBytes;
  if (k > 0) std::memcpy(p, f.descriptors.data(), k * 32);
  p += k * 32;
  for (float v : f.keypoints) {
    Store<int16_t>(p, static_cast<int16_t>(std::round(std::ldexp(v, -e_k))));
    p += 2;
  }
  for (float v : f.depths) {
    Store<uint16_t>(p, v > 0 ? FloatToHalf(std::ldexp(v, -e_d)) : uint16_t{0});
    p += 2;
  }
  return out;
}

PackedKeyframe PackedKeyframe::FromBytes(std::span<const uint8_t> bytes) {
  SL_CHECK_MSG(bytes.size() >= kHeaderBytes,
               "packed keyframe: expected at least {} bytes (the header), got {}", kHeaderBytes,
               bytes.size());
  const uint8_t* d = bytes.data();
  SL_CHECK_MSG(d[kOffVersion] == kVersion, "packed keyframe: expected version {}, got {}", kVersion,
               d[kOffVersion]);
  const uint8_t flags = d[kOffFlags];
  SL_CHECK_MSG((flags & ~0x0fu) == 0, "packed keyframe: unknown flags 0x{:02x}", flags);
  const size_t k = Load<uint16_t>(d + kOffK);
  const size_t expected = RecordBytes(k, flags & kFlagDepths);
  SL_CHECK_MSG(bytes.size() == expected, "packed keyframe: {} features{} need {} bytes, got {}", k,
               (flags & kFlagDepths) ? " with depths" : "", expected, bytes.size());
  PackedKeyframe out;
  out.words_.reset(new uint64_t[(expected + 7) / 8]());
  std::memcpy(out.words_.get(), d, expected);
  SL_CHECK_MSG(std::isfinite(out.timestamp()) && std::isfinite(out.focal_px()),
               "packed keyframe {}: timestamp or focal length is not finite", out.id());
  if (out.has_pose()) {
    const Sim3d pose = out.world_from_cam();
    SL_CHECK_MSG(pose.translation.allFinite() && std::isfinite(pose.scale) && pose.scale > 0,
                 "packed keyframe {}: pose is not finite or its scale is not positive", out.id());
    // Three components of a unit quaternion: their squares sum to at most 1 (Pack writes at most
    // about 3/4, the largest component being at least as large as each).
    double sum = 0.0;
    for (int i = 0; i < 3; ++i) {
      const double q = Load<int16_t>(d + kOffRotation + 2 * i) * kRotationStep;
      sum += q * q;
    }
    SL_CHECK_MSG(sum <= 1.0,
                 "packed keyframe {}: rotation code is not three components of a unit quaternion",
                 out.id());
  }
  // Pack writes exponents in [kMinExponent, kMaxExponent] and non-negative finite depths; even
  // inside that range an exponent byte can push a coordinate or a depth past float's range.
  for (const size_t offset : {kOffKeypointExp, kOffDepthExp}) {
    const int e = static_cast<int8_t>(d[offset]);
    SL_CHECK_MSG(e >= kMinExponent && e <= kMaxExponent,
                 "packed keyframe {}: {} exponent {} outside [{}, {}]", out.id(),
                 offset == kOffKeypointExp ? "keypoint" : "depth", e, kMinExponent, kMaxExponent);
  }
  const uint8_t* codes = d + kHeaderBytes + out.size() * 32;
  for (size_t i = 0; i < out.size(); ++i) {
    SL_CHECK_MSG(std::isfinite(out.keypoint_x(i)) && std::isfinite(out.keypoint_y(i)),
                 "packed keyframe {}: keypoint {} is not finite", out.id(), i);
    SL_CHECK_MSG(
        Load<int16_t>(codes + 4 * i) != INT16_MIN && Load<int16_t>(codes + 4 * i + 2) != INT16_MIN,
        "packed keyframe {}: keypoint {} has code -32768 (Pack writes +-32767 at most)", out.id(),
        i);
    const float depth = out.depth(i);
    SL_CHECK_MSG(std::isfinite(depth) && depth >= 0.0f,
                 "packed keyframe {}: depth {} is not finite or negative", out.id(), i);
    if (out.has_depths()) {
      // Pack scales depths below 32768 before the half conversion.
      const float half = HalfToFloat(Load<uint16_t>(codes + out.size() * 4 + 2 * i));
      SL_CHECK_MSG(half < 32768.0f,
                   "packed keyframe {}: depth {} has half code {} (Pack writes < 32768)", out.id(),
                   i, half);
    }
  }
  return out;
}

PackedKeyframe::Fields PackedKeyframe::Unpack() const {
  Fields f;
  f.id = id();
  f.timestamp = timestamp();
  f.has_pose = has_pose();
  if (f.has_pose) f.world_from_cam = world_from_cam();
  f.focal_px = focal_px();
  const auto desc = descriptors();
  f.descriptors.assign(desc.begin(), desc.end());
  const size_t k = size();
  f.keypoints.resize(2 * k);
  for (size_t i = 0; i < k; ++i) {
    f.keypoints[2 * i] = keypoint_x(i);
    f.keypoints[2 * i + 1] = keypoint_y(i);
  }
  if (has_depths()) {
    f.depths.resize(k);
    for (size_t i = 0; i < k; ++i) f.depths[i] = depth(i);
  }
  return f;
}

std::span<const uint8_t> PackedKeyframe::bytes() const { return {data(), ByteSize()}; }

size_t PackedKeyframe::ByteSize() const {
  if (!words_) return 0;
  return RecordBytes(size(), has_depths());
}

namespace {
const uint8_t* Header(const uint64_t* words) {
  return words ? reinterpret_cast<const uint8_t*>(words) : kEmptyHeader;
}
}  // namespace

int64_t PackedKeyframe::id() const { return Load<int64_t>(Header(words_.get()) + kOffId); }
double PackedKeyframe::timestamp() const {
  return Load<double>(Header(words_.get()) + kOffTimestamp);
}
bool PackedKeyframe::has_pose() const { return Header(words_.get())[kOffFlags] & kFlagPose; }
bool PackedKeyframe::has_depths() const { return Header(words_.get())[kOffFlags] & kFlagDepths; }
float PackedKeyframe::focal_px() const { return Load<float>(Header(words_.get()) + kOffFocal); }
size_t PackedKeyframe::size() const { return Load<uint16_t>(Header(words_.get()) + kOffK); }

Sim3d PackedKeyframe::world_from_cam() const {
  if (!has_pose()) return Sim3d::Identity();
  const uint8_t* d = Header(words_.get());
  RotationCode c;
  c.largest = (d[kOffFlags] >> kRotationIndexShift) & 3;
  for (int i = 0; i < 3; ++i) c.codes[i] = Load<int16_t>(d + kOffRotation + 2 * i);
  Eigen::Vector3d t;
  for (int i = 0; i < 3; ++i) t[i] = Load<float>(d + kOffTranslation + 4 * i);
  return Sim3d(Load<float>(d + kOffScale), DecodeRotation(c), t);
}

std::span<const Descriptor256> PackedKeyframe::descriptors() const {
  if (!words_) return {};
  return {reinterpret_cast<const Descriptor256*>(words_.get() + kHeaderBytes / 8), size()};
}

float PackedKeyframe::keypoint_x(size_t i) const {
  const uint8_t* d = data();
  const size_t k = size();
  return std::ldexp(static_cast<float>(Load<int16_t>(d + kHeaderBytes + k * 32 + 4 * i)),
                    static_cast<int8_t>(d[kOffKeypointExp]));
}
float PackedKeyframe::keypoint_y(size_t i) const {
  const uint8_t* d = data();
  const size_t k = size();
  return std::ldexp(static_cast<float>(Load<int16_t>(d + kHeaderBytes + k * 32 + 4 * i + 2)),
                    static_cast<int8_t>(d[kOffKeypointExp]));
}
float PackedKeyframe::depth(size_t i) const {
  if (!has_depths()) return 0.0f;
  const uint8_t* d = data();
  const size_t k = size();
  return std::ldexp(HalfToFloat(Load<uint16_t>(d + kHeaderBytes + k * 36 + 2 * i)),
                    static_cast<int8_t>(d[kOffDepthExp]));
}

}  // namespace sparseloop
