#include "sparseloop/eval/associate.h"

#include <gtest/gtest.h>

namespace sparseloop {
namespace {

Trajectory FromTimes(const std::vector<double>& times) {
  Trajectory t;
  for (size_t i = 0; i < times.size(); ++i) {
    StampedPose p;
    p.timestamp = times[i];
    p.frame = static_cast<int64_t>(i);
    t.poses.push_back(p);
  }
  return t;
}

Trajectory FromFrames(const std::vector<int64_t>& frames) {
  Trajectory t;
  for (int64_t f : frames) {
    StampedPose p;
    p.frame = f;
    p.timestamp = static_cast<double>(f);
    t.poses.push_back(p);
  }
  return t;
}

using Pairs = std::vector<std::pair<size_t, size_t>>;

TEST(Associate, NearestWithinMaxDt) {
  // est 0.0 -> gt 0.005 (dt 0.005); est 0.1 -> gt 0.1 (dt 0, beats gt 0.11 at 0.01);
  // est 0.2 has nothing within 0.02; est 0.305 -> gt 0.31.
  const auto est = FromTimes({0.0, 0.1, 0.2, 0.305});
  const auto gt = FromTimes({0.005, 0.1, 0.11, 0.31, 0.5});
  AssociationOptions options;
  options.max_dt = 0.02;
  EXPECT_EQ(Associate(est, gt, options).pairs, (Pairs{{0, 0}, {1, 1}, {3, 3}}));
  options.max_dt = 0.001;  // only the exact match survives
  EXPECT_EQ(Associate(est, gt, options).pairs, (Pairs{{1, 1}}));
}

TEST(Associate, EachGtPoseUsedOnce) {
  // Both estimates are nearest to gt 0.1; the closer one (est 0) wins it, est 1 takes gt 0.13.
  const auto est = FromTimes({0.1, 0.104});
  const auto gt = FromTimes({0.1, 0.13});
  AssociationOptions options;
  options.max_dt = 0.03;
  EXPECT_EQ(Associate(est, gt, options).pairs, (Pairs{{0, 0}, {1, 1}}));
  // With a tighter window est 1 has no free partner left.
  options.max_dt = 0.01;
  EXPECT_EQ(Associate(est, gt, options).pairs, (Pairs{{0, 0}}));
}

TEST(Associate, OffsetIsAddedToEstimate) {
  const auto est = FromTimes({1.0, 2.0});
  const auto gt = FromTimes({11.0, 12.0});
  AssociationOptions options;
  EXPECT_TRUE(Associate(est, gt, options).pairs.empty());
  options.offset = 10.0;
  EXPECT_EQ(Associate(est, gt, options).pairs, (Pairs{{0, 0}, {1, 1}}));
}

TEST(Associate, ByFrameIndex) {
  AssociationOptions options;
  options.method = AssociationMethod::kIndex;
  EXPECT_EQ(Associate(FromFrames({2, 3, 5}), FromFrames({0, 1, 2, 3, 4}), options).pairs,
            (Pairs{{0, 2}, {1, 3}}));
  EXPECT_THROW(Associate(FromFrames({1, 1}), FromFrames({0, 1}), options), std::invalid_argument);
  EXPECT_THROW(Associate(FromFrames({1}), FromFrames({1, 1}), options), std::invalid_argument);
}

TEST(Associate, InvalidOptionsAndParsing) {
  AssociationOptions options;
  options.max_dt = -1.0;
  EXPECT_THROW(options.Check(), std::invalid_argument);
  EXPECT_EQ(ParseAssociationMethod("time"), AssociationMethod::kTimestamp);
  EXPECT_EQ(ParseAssociationMethod("index"), AssociationMethod::kIndex);
  EXPECT_THROW(ParseAssociationMethod("nearest"), std::invalid_argument);
}

}  // namespace
}  // namespace sparseloop
