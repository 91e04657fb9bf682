// The raw pose track (src/loop/pose_track.h): segments, the reset rules and the raw step, against
// the values worked out by hand for each case.
#include "loop/pose_track.h"

#include <gtest/gtest.h>

namespace sparseloop {
namespace {

Sim3d At(double x, double yaw_deg = 0.0, double scale = 1.0) {
  Sim3d p;
  p.translation = Eigen::Vector3d(x, 0, 0);
  p.rotation =
      Eigen::Quaterniond(Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitY()));
  p.scale = scale;
  return p;
}

// Six keyframes one unit apart: the segment has 5 steps, so the jump rules apply from here.
PoseTrack SixSteps() {
  PoseTrack t(PoseTrack::Rules{});
  for (int i = 0; i < 6; ++i) {
    const std::optional<Sim3d> pose = At(i);
    EXPECT_EQ(t.Classify(pose, false), PoseReset::kNone) << i;
    EXPECT_DOUBLE_EQ(t.Advance(pose, PoseReset::kNone), i == 0 ? 0.0 : 1.0) << i;
    t.Store(pose->translation);
  }
  return t;
}

TEST(PoseTrack, EachRuleAndTheCallerStartASegment) {
  const PoseTrack t = SixSteps();
  EXPECT_EQ(t.Classify(At(6), false), PoseReset::kNone);
  EXPECT_EQ(t.Classify(At(6), true), PoseReset::kCaller);
  EXPECT_EQ(t.Classify(At(5 + 19.9), false), PoseReset::kNone);  // 19.9 x the usual step
  EXPECT_EQ(t.Classify(At(5 + 20.1), false), PoseReset::kTranslationJump);
  EXPECT_EQ(t.Classify(At(6, 89), false), PoseReset::kNone);
  EXPECT_EQ(t.Classify(At(6, 91), false), PoseReset::kRotationJump);
  EXPECT_EQ(t.Classify(At(6, 0, 1.9), false), PoseReset::kNone);
  EXPECT_EQ(t.Classify(At(6, 0, 2.1), false), PoseReset::kScaleJump);
  EXPECT_EQ(t.Classify(At(6, 0, 1 / 2.1), false), PoseReset::kScaleJump);
  EXPECT_EQ(t.Classify(std::nullopt, true), PoseReset::kNone);  // no pose, no segment
  // Rules off (0): only the caller's flag.
  PoseTrack off(PoseTrack::Rules{0, 0, 0});
  for (int i = 0; i < 6; ++i) off.Advance(At(i), PoseReset::kNone);
  EXPECT_EQ(off.Classify(At(1000, 180, 100), false), PoseReset::kNone);
  EXPECT_EQ(off.Classify(At(6), true), PoseReset::kCaller);
}

TEST(PoseTrack, FewStepsAndTheFirstPoseNeverReset) {
  PoseTrack t(PoseTrack::Rules{});
  EXPECT_EQ(t.Classify(At(0), true), PoseReset::kNone);  // nothing before it
  t.Advance(At(0), PoseReset::kNone);
  t.Advance(At(1), PoseReset::kNone);
  // Two poses far apart (photos of one place): 4 steps are too few to call a jump.
  EXPECT_EQ(t.Classify(At(500), false), PoseReset::kNone);
}

TEST(PoseTrack, SegmentsOfStoredKeyframesAndTheStepAcrossAReset) {
  PoseTrack t = SixSteps();
  EXPECT_EQ(t.current_segment(), 0);
  // A reset: the new world frame's pose is far away; the step stands in with the last one (1).
  const std::optional<Sim3d> jumped = At(1000);
  const PoseReset reset = t.Classify(jumped, false);
  ASSERT_EQ(reset, PoseReset::kTranslationJump);
  EXPECT_DOUBLE_EQ(t.Advance(jumped, reset), 1.0);
  t.Store(jumped->translation);
  EXPECT_EQ(t.current_segment(), 1);
  // A keyframe without a pose: in the current segment, at the last posed place, no step.
  EXPECT_DOUBLE_EQ(t.Advance(std::nullopt, PoseReset::kNone), 0.0);
  t.Store(std::nullopt);
  EXPECT_EQ(t.last_position(), Eigen::Vector3d(1000, 0, 0));
  // The next pose steps from the reset's pose, not across the gap.
  EXPECT_DOUBLE_EQ(t.Advance(At(1002.5), PoseReset::kNone), 2.5);
  t.Store(Eigen::Vector3d(1002.5, 0, 0));
  EXPECT_TRUE(t.SameSegment(0, 5));
  EXPECT_FALSE(t.SameSegment(5, 6));
  EXPECT_TRUE(t.SameSegment(6, 7));
  EXPECT_TRUE(t.SameSegment(7, 8));
  // The segment's statistics restarted: 1 step, so no jump rule applies yet.
  EXPECT_EQ(t.Classify(At(5000), false), PoseReset::kNone);
}

}  // namespace
}  // namespace sparseloop
