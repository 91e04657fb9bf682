#include "sparseloop/core/packed_keyframe.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace sparseloop {
namespace {

using Fields = PackedKeyframe::Fields;

Fields RandomFields(std::mt19937_64& rng, size_t k, bool depths, double keypoint_range,
                    double depth_scale) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<uint64_t> bits;
  Fields f;
  f.id = static_cast<int64_t>(bits(rng) >> 2);
  f.timestamp = 1403636579.763555527 + u(rng);
  f.has_pose = true;
  f.world_from_cam.rotation = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
  f.world_from_cam.translation = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 300.0;
  f.world_from_cam.scale = std::exp(u(rng));
  f.focal_px = 718.856f;
  for (size_t i = 0; i < k; ++i) {
    f.descriptors.push_back({bits(rng), bits(rng), bits(rng), bits(rng)});
    f.keypoints.push_back(static_cast<float>(u(rng) * keypoint_range));
    f.keypoints.push_back(static_cast<float>(u(rng) * keypoint_range * 0.6));
    if (depths) f.depths.push_back(static_cast<float>(depth_scale * std::exp(2.0 * u(rng))));
  }
  if (depths && k > 2) f.depths[1] = -1.0f;  // unknown
  return f;
}

std::vector<uint8_t> Bytes(const PackedKeyframe& p) { return {p.bytes().begin(), p.bytes().end()}; }

TEST(HalfFloat, EveryHalfDecodesAndEncodesToItself) {
  for (uint32_t h = 0; h < 65536; ++h) {
    const float f = HalfToFloat(static_cast<uint16_t>(h));
    if (std::isnan(f)) continue;
    ASSERT_EQ(FloatToHalf(f), h) << "half 0x" << std::hex << h << " = " << f;
  }
}

TEST(HalfFloat, RoundsToNearestEven) {
  EXPECT_EQ(HalfToFloat(FloatToHalf(1.0f)), 1.0f);
  EXPECT_EQ(HalfToFloat(FloatToHalf(65504.0f)), 65504.0f);
  EXPECT_TRUE(std::isinf(HalfToFloat(FloatToHalf(65520.0f))));
  EXPECT_EQ(HalfToFloat(FloatToHalf(65519.0f)), 65504.0f);
  EXPECT_EQ(HalfToFloat(FloatToHalf(std::ldexp(1.0f, -24))), std::ldexp(1.0f, -24));
  EXPECT_EQ(HalfToFloat(FloatToHalf(std::ldexp(1.0f, -25))), 0.0f);         // tie -> even (0)
  EXPECT_EQ(HalfToFloat(FloatToHalf(1.0f + std::ldexp(1.0f, -11))), 1.0f);  // tie -> even
  EXPECT_EQ(HalfToFloat(FloatToHalf(1.0f + 3 * std::ldexp(1.0f, -11))),
            1.0f + std::ldexp(1.0f, -9));  // tie -> even (up)
  // Against a plain reference: the nearest half by search, on random floats.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<float> u(-70000.0f, 70000.0f);
  for (int i = 0; i < 20000; ++i) {
    const float v = i % 2 ? u(rng) : u(rng) * 1e-4f;
    const float got = HalfToFloat(FloatToHalf(v));
    if (std::abs(v) >= 65520.0f) {
      EXPECT_TRUE(std::isinf(got));
      continue;
    }
    const float below = HalfToFloat(FloatToHalf(v) - (got > v ? (v > 0 ? 1 : -1) : 0));
    EXPECT_LE(std::abs(got - v), std::abs(below - v) + 1e-12f) << v;
    EXPECT_LE(std::abs(got - v), std::max(std::abs(v) * 4.9e-4f, std::ldexp(1.0f, -25))) << v;
  }
}

TEST(PackedKeyframe, K15WithPoseKeypointsAndDepthsFitsIn640Bytes) {
  std::mt19937_64 rng(1);
  const PackedKeyframe p = PackedKeyframe::Pack(RandomFields(rng, 15, true, 1.2, 10.0));
  EXPECT_EQ(p.bytes().size(), 618u);
  EXPECT_LE(p.Bytes(), 640u);
  EXPECT_EQ(p.size(), 15u);
  EXPECT_TRUE(p.has_depths());
  const PackedKeyframe q = PackedKeyframe::Pack(RandomFields(rng, 300, false, 1.2, 10.0));
  EXPECT_EQ(q.bytes().size(), 48u + 300u * 36u);
}

TEST(PackedKeyframe, QuantisationStaysWithinItsStatedBounds) {
  std::mt19937_64 rng(2);
  for (int trial = 0; trial < 300; ++trial) {
    const double range = std::ldexp(1.0, trial % 12 - 6);  // keypoints from 1/64 to 32
    const double depth_scale = std::ldexp(1.0, trial % 30 - 15);
    const Fields f = RandomFields(rng, 1 + trial % 40, trial % 3 != 0, range, depth_scale);
    const PackedKeyframe p = PackedKeyframe::Pack(f);
    const Fields g = p.Unpack();
    ASSERT_EQ(g.id, f.id);
    ASSERT_EQ(g.timestamp, f.timestamp);
    ASSERT_EQ(g.focal_px, f.focal_px);
    ASSERT_EQ(g.descriptors, f.descriptors);
    ASSERT_EQ(g.keypoints.size(), f.keypoints.size());
    ASSERT_EQ(g.depths.size(), f.depths.size());
    float max_kp = 0;
    for (float v : f.keypoints) max_kp = std::max(max_kp, std::abs(v));
    for (size_t i = 0; i < f.keypoints.size(); ++i)  // int16 over the range: 2^-15 of it
      EXPECT_LE(std::abs(g.keypoints[i] - f.keypoints[i]), max_kp * std::ldexp(1.0f, -15));
    for (size_t i = 0; i < f.depths.size(); ++i) {
      if (f.depths[i] <= 0) {
        EXPECT_EQ(g.depths[i], 0.0f);
        continue;
      }
      EXPECT_NEAR(g.depths[i], f.depths[i], f.depths[i] * 4.9e-4) << depth_scale;
    }
    const Sim3d& a = f.world_from_cam;
    const Sim3d& b = g.world_from_cam;
    EXPECT_LT(a.rotation.angularDistance(b.rotation), 1e-4);
    EXPECT_NEAR(b.rotation.norm(), 1.0, 1e-12);
    EXPECT_LT((a.translation - b.translation).norm(), 1e-4);
    EXPECT_NEAR(b.scale, a.scale, a.scale * 1e-7);
  }
}

TEST(PackedKeyframe, PackingWhatItDecodesGivesTheSameBytes) {
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 2000; ++trial) {
    Fields f = RandomFields(rng, trial % 20, trial % 2 == 0, std::ldexp(1.0, trial % 9 - 4),
                            std::ldexp(1.0, trial % 40 - 20));
    if (trial % 4 == 1) {  // near ties of the largest quaternion component
      const double e = 1e-5 * u(rng);
      f.world_from_cam.rotation = Eigen::Quaterniond(0.5 + e, 0.5 - e, 0.5, 0.5).normalized();
    }
    if (trial % 7 == 3) f.has_pose = false;
    const PackedKeyframe p = PackedKeyframe::Pack(f);
    const PackedKeyframe again = PackedKeyframe::Pack(p.Unpack());
    ASSERT_EQ(Bytes(again), Bytes(p)) << "trial " << trial;
    const PackedKeyframe read = PackedKeyframe::FromBytes(p.bytes());
    ASSERT_EQ(Bytes(read), Bytes(p));
    const PackedKeyframe copy = p;
    ASSERT_EQ(Bytes(copy), Bytes(p));
  }
}

TEST(PackedKeyframe, AccessorsAgreeWithUnpack) {
  std::mt19937_64 rng(5);
  const PackedKeyframe p = PackedKeyframe::Pack(RandomFields(rng, 15, true, 1.0, 5.0));
  const Fields f = p.Unpack();
  ASSERT_EQ(p.descriptors().size(), 15u);
  for (size_t i = 0; i < 15; ++i) {
    EXPECT_EQ(p.descriptors()[i], f.descriptors[i]);
    EXPECT_EQ(p.keypoint_x(i), f.keypoints[2 * i]);
    EXPECT_EQ(p.keypoint_y(i), f.keypoints[2 * i + 1]);
    EXPECT_EQ(p.depth(i), f.depths[i]);
  }
  EXPECT_EQ(p.id(), f.id);
  EXPECT_TRUE(p.has_pose());
  EXPECT_EQ(p.world_from_cam().translation, f.world_from_cam.translation);
}

TEST(PackedKeyframe, EmptyRecordIsTheOwningPointerOnly) {
  const PackedKeyframe empty;
  EXPECT_EQ(empty.Bytes(), sizeof(void*));
  EXPECT_EQ(empty.size(), 0u);
  EXPECT_FALSE(empty.has_pose());
  EXPECT_TRUE(empty.descriptors().empty());
  const PackedKeyframe none = PackedKeyframe::Pack({});
  EXPECT_EQ(none.bytes().size(), PackedKeyframe::kHeaderBytes);
  EXPECT_EQ(Bytes(PackedKeyframe::Pack(none.Unpack())), Bytes(none));
}

TEST(PackedKeyframe, BadInputIsRefusedWithAReason) {
  std::mt19937_64 rng(6);
  Fields f = RandomFields(rng, 5, true, 1.0, 1.0);
  const PackedKeyframe p = PackedKeyframe::Pack(f);
  std::vector<uint8_t> b = Bytes(p);
  auto refused = [](std::vector<uint8_t> bytes, const std::string& expected) {
    try {
      PackedKeyframe::FromBytes(bytes);
      ADD_FAILURE() << "accepted, expected: " << expected;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  };
  refused({b.begin(), b.end() - 1}, "need");
  refused({b.begin(), b.begin() + 20}, "at least 48 bytes");
  std::vector<uint8_t> v = b;
  v[44] = 9;
  refused(v, "version");
  v = b;
  v[45] |= 0x40;
  refused(v, "flags");
  // Corrupt values inside a well-formed record: rotation codes beyond a unit quaternion (bytes
  // 36-41), a keypoint exponent outside Pack's range or one that overflows float (byte 46), a
  // half-float infinity as a depth (the last two bytes of the record: f has depths).
  v = b;
  for (size_t i = 36; i < 42; i += 2) {
    v[i] = 0xff;
    v[i + 1] = 0x7f;
  }
  refused(v, "rotation code");
  v = b;
  v[46] = 127;
  refused(v, "keypoint exponent 127 outside [-100, 120]");
  v = b;
  v[46] = 120;
  refused(v, "is not finite");
  v = b;
  v[48 + 5 * 32] = 0x00;  // keypoint 0's x code -32768: Pack clamps to +-32767
  v[48 + 5 * 32 + 1] = 0x80;
  refused(v, "keypoint 0 has code -32768");
  v = b;
  v[v.size() - 2] = 0x00;  // 32768 as a half: Pack scales depths below it
  v[v.size() - 1] = 0x78;
  refused(v, "depth 4 has half code 32768");
  v = b;
  v[v.size() - 1] = 0xbc;  // -1.0 as a half: Pack stores unknown depths as 0, never negative
  refused(v, "depth 4 is not finite or negative");
  v = b;
  v[v.size() - 2] = 0x00;
  v[v.size() - 1] = 0x7c;
  refused(v, "depth 4 is not finite or negative");
  Fields g = f;
  g.keypoints.pop_back();
  EXPECT_THROW(PackedKeyframe::Pack(g), std::invalid_argument);
  g = f;
  g.depths.pop_back();
  EXPECT_THROW(PackedKeyframe::Pack(g), std::invalid_argument);
  g = f;
  g.keypoints[3] = std::nanf("");
  EXPECT_THROW(PackedKeyframe::Pack(g), std::invalid_argument);
  g = f;
  g.world_from_cam.translation.x() = 1e300;
  EXPECT_THROW(PackedKeyframe::Pack(g), std::invalid_argument);
  g = f;
  g.world_from_cam.rotation.coeffs() *= 1.1;
  EXPECT_THROW(PackedKeyframe::Pack(g), std::invalid_argument);
}

}  // namespace
}  // namespace sparseloop
