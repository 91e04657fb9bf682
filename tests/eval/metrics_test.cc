#include "sparseloop/eval/metrics.h"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "eval/eval_test_util.h"
#include "test_util.h"

namespace sparseloop {
namespace {

constexpr double kRadToDegPer100m = 180.0 / std::numbers::pi * 100.0;

TEST(Statistics, KnownAnswers) {
  const auto even = ComputeStatistics({4.0, 1.0, 3.0, 2.0});
  EXPECT_EQ(even.count, 4u);
  EXPECT_DOUBLE_EQ(even.mean, 2.5);
  EXPECT_DOUBLE_EQ(even.median, 2.5);
  EXPECT_DOUBLE_EQ(even.rmse, std::sqrt(30.0 / 4.0));
  EXPECT_DOUBLE_EQ(even.std, std::sqrt(1.25));
  EXPECT_EQ(even.min, 1.0);
  EXPECT_EQ(even.max, 4.0);
  EXPECT_EQ(even.errors, (std::vector<double>{4.0, 1.0, 3.0, 2.0}));
  EXPECT_DOUBLE_EQ(ComputeStatistics({3.0, 1.0, 2.0}).median, 2.0);
  const auto empty = ComputeStatistics({});
  EXPECT_EQ(empty.count, 0u);
  EXPECT_EQ(empty.rmse, 0.0);
}

TEST(Ate, KnownOffset) {
  // Every estimate point 0.5 m off along y, except one 2 m off: errors {0.5, 0.5, 0.5, 2}.
  const std::vector<Eigen::Vector3d> gt = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}};
  const std::vector<Eigen::Vector3d> est = {{0, 0.5, 0}, {1, 0.5, 0}, {2, 0.5, 0}, {3, 2, 0}};
  const auto ate = ComputeAte(gt, est);
  EXPECT_DOUBLE_EQ(ate.rmse, std::sqrt((3 * 0.25 + 4.0) / 4.0));
  EXPECT_DOUBLE_EQ(ate.mean, 3.5 / 4.0);
  EXPECT_DOUBLE_EQ(ate.median, 0.5);
  EXPECT_DOUBLE_EQ(ate.max, 2.0);
  // The transform is applied to the estimate first.
  const Sim3d shift(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, -0.5, 0));
  EXPECT_DOUBLE_EQ(ComputeAte(gt, est, shift).max, 1.5);
  EXPECT_THROW(ComputeAte(gt, {}), std::invalid_argument);
}

// gt: straight line along +z, 1 m per frame, identity orientation.
std::vector<Rigid3d> StraightLine(size_t n) {
  std::vector<Rigid3d> poses(n);
  for (size_t i = 0; i < n; ++i)
    poses[i].translation = Eigen::Vector3d(0, 0, static_cast<double>(i));
  return poses;
}

// A delta in frames of 1e20 overflowed size_t (an endless loop); 2^64 was std::bad_alloc. The
// delta is bounded (kMaxRpeDeltaFrames), and a delta past the trajectory gives no pair.
TEST(Rpe, HugeDeltaInFramesIsRefusedAndOneBeyondTheTrajectoryGivesNoPair) {
  const std::vector<Rigid3d> line = StraightLine(40);
  for (const double huge : {1e20, 1.9e19, 18446744073709551616.0, 1e9 + 1}) {
    RpeOptions o;
    o.delta = huge;
    EXPECT_THROW(RpePairs(line, o), std::invalid_argument) << huge;
  }
  for (const bool all_pairs : {false, true}) {
    RpeOptions o;
    o.delta = kMaxRpeDeltaFrames;
    o.all_pairs = all_pairs;
    EXPECT_TRUE(RpePairs(line, o).empty());
    o.delta = 39;
    EXPECT_EQ(RpePairs(line, o).size(), 1u);
  }
}

TEST(Rpe, ScaledTranslationKnownAnswers) {
  const auto gt = StraightLine(10);
  auto est = gt;
  for (auto& p : est) p.translation *= 1.1;  // every metre travelled is 1.1 m in the estimate
  RpeOptions options;
  auto r = ComputeRpe(gt, est, options);
  ASSERT_EQ(r.translation.count, 9u);  // (0,1) ... (8,9)
  EXPECT_NEAR(r.translation.max, 0.1, 1e-12);
  EXPECT_NEAR(r.translation.min, 0.1, 1e-12);
  ASSERT_TRUE(r.rotation_deg);
  EXPECT_NEAR(r.rotation_deg->max, 0.0, 1e-12);

  options.delta = 3;  // evo consecutive ids 0, 3, 6, 9
  r = ComputeRpe(gt, est, options);
  EXPECT_EQ(r.pairs, (std::vector<std::pair<size_t, size_t>>{{0, 3}, {3, 6}, {6, 9}}));
  EXPECT_NEAR(r.translation.rmse, 0.3, 1e-12);

  options.all_pairs = true;  // (0,3) ... (6,9)
  EXPECT_EQ(ComputeRpe(gt, est, options).translation.count, 7u);

  // Metres: evo's path rule emits ids where the accumulated path reaches 2.5 m: 3, 6, 9.
  options = RpeOptions{};
  options.unit = RpeUnit::kMeters;
  options.delta = 2.5;
  r = ComputeRpe(gt, est, options);
  EXPECT_EQ(r.pairs, (std::vector<std::pair<size_t, size_t>>{{3, 6}, {6, 9}}));
  EXPECT_NEAR(r.translation.mean, 0.3, 1e-12);
}

TEST(Rpe, RotationDriftKnownAnswer) {
  // Estimate rolls 0.01 rad per frame about the direction of travel: translation stays exact.
  const auto gt = StraightLine(20);
  auto est = gt;
  for (size_t i = 0; i < est.size(); ++i) {
    est[i].rotation = Eigen::AngleAxisd(0.01 * static_cast<double>(i), Eigen::Vector3d::UnitZ());
  }
  const auto r = ComputeRpe(gt, est, {});
  ASSERT_TRUE(r.rotation_deg);
  EXPECT_NEAR(r.rotation_deg->mean, 0.01 * 180.0 / std::numbers::pi, 1e-10);
  EXPECT_NEAR(r.translation.max, 0.0, 1e-12);
  // Without estimate orientation the rotation is not computable.
  EXPECT_FALSE(ComputeRpe(gt, est, {}, false).rotation_deg);
}

// Number of devkit segments of length `len` on StraightLine(n): first frames 0, 10, ... whose
// last frame first + len + 1 (first distance strictly beyond len) exists.
size_t SegmentsOnLine(size_t n, double len) {
  size_t count = 0;
  for (size_t first = 0; first < n; first += 10) {
    if (first + static_cast<size_t>(len) + 1 < n) ++count;
  }
  return count;
}

TEST(Kitti, ScaleErrorGivesKnownTranslationError) {
  // est = gt with translation scaled by 1.01 along a straight line. The devkit's last frame is
  // the first whose distance exceeds len, i.e. len + 1 m away, so each segment has
  // t_err = 0.01 * (len + 1) / len exactly, and no rotation error.
  const size_t n = 1000;
  const auto gt = StraightLine(n);
  auto est = gt;
  for (auto& p : est) p.translation *= 1.01;
  const auto k = ComputeKittiMetric(gt, est);
  ASSERT_EQ(k.status, KittiStatus::kOk);
  double sum = 0.0;
  size_t total = 0;
  ASSERT_EQ(k.per_length.size(), 8u);
  for (const auto& per : k.per_length) {
    EXPECT_EQ(per.count, SegmentsOnLine(n, per.length)) << per.length;
    EXPECT_NEAR(per.t_err_pct, (per.length + 1.0) / per.length, 1e-9) << per.length;
    ASSERT_TRUE(per.r_err_deg_per_100m);
    EXPECT_NEAR(*per.r_err_deg_per_100m, 0.0, 1e-9);
    sum += per.count * (per.length + 1.0) / per.length;
    total += per.count;
  }
  EXPECT_EQ(k.num_segments, total);
  for (const auto& seg : k.segments) {
    EXPECT_EQ(seg.last_frame, seg.first_frame + static_cast<size_t>(seg.length) + 1);
    EXPECT_NEAR(seg.speed, seg.length / ((seg.length + 2.0) * 0.1), 1e-9);
  }
  EXPECT_NEAR(*k.t_err_pct, sum / total, 1e-9);
  EXPECT_GT(*k.t_err_pct, 1.0);
  EXPECT_LT(*k.t_err_pct, 1.011);
}

TEST(Kitti, RollDriftGivesKnownRotationError) {
  // Estimate rolls k rad per frame about the forward (z) axis, positions exact: the relative
  // rotation over a segment is k * (len + 1) and translation error is zero.
  const size_t n = 900;
  const double k = 1e-4;
  const auto gt = StraightLine(n);
  auto est = gt;
  for (size_t i = 0; i < n; ++i) {
    est[i].rotation = Eigen::AngleAxisd(k * static_cast<double>(i), Eigen::Vector3d::UnitZ());
  }
  const auto r = ComputeKittiMetric(gt, est);
  ASSERT_EQ(r.status, KittiStatus::kOk);
  EXPECT_EQ(r.per_length.size(), 8u);
  for (const auto& per : r.per_length) {
    EXPECT_NEAR(per.t_err_pct, 0.0, 1e-9);
    ASSERT_TRUE(per.r_err_deg_per_100m);
    EXPECT_NEAR(*per.r_err_deg_per_100m, k * (per.length + 1.0) / per.length * kRadToDegPer100m,
                1e-6);
  }
  // Positions-only view of the same estimate: no rotation metric, translation still exact.
  const auto p = ComputeKittiMetric(gt, est, {}, false);
  EXPECT_FALSE(p.r_err_deg_per_100m);
  EXPECT_NEAR(*p.t_err_pct, 0.0, 1e-12);
}

TEST(Kitti, TooShortHasNoSegments) {
  const auto gt = StraightLine(50);
  const auto r = ComputeKittiMetric(gt, gt);
  EXPECT_EQ(r.status, KittiStatus::kNoSegments);
  EXPECT_FALSE(r.t_err_pct);
  EXPECT_TRUE(r.per_length.empty());
  KittiOptions bad;
  bad.step_size = 0;
  EXPECT_THROW(ComputeKittiMetric(gt, gt, bad), std::invalid_argument);
}

TEST(Kitti, RigidAlignmentDoesNotChangeFullPoseMetric) {
  // Relative metrics on full poses are invariant to a rigid change of the estimate's world frame.
  auto rng = test::SeededRng(7);
  const auto traj = test::MakeLoopTrajectory(2000, 200.0);
  std::vector<Rigid3d> gt, est, moved;
  std::normal_distribution<double> noise(0.0, 0.05);
  Sim3d rigid = test::RandomSim3(rng);
  rigid.scale = 1.0;
  for (const auto& p : traj.poses) {
    gt.push_back(p.world_from_cam);
    Rigid3d e = p.world_from_cam;
    e.translation += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    e.rotation = e.rotation * ExpSO3(Eigen::Vector3d(noise(rng), noise(rng), noise(rng)) * 0.01);
    est.push_back(e);
    moved.push_back(ApplyAlignment(rigid, e));
  }
  const auto a = ComputeKittiMetric(gt, est);
  const auto b = ComputeKittiMetric(gt, moved);
  ASSERT_EQ(a.status, KittiStatus::kOk);
  EXPECT_GT(*a.t_err_pct, 0.0);
  EXPECT_NEAR(*a.t_err_pct, *b.t_err_pct, 1e-9);
  EXPECT_NEAR(*a.r_err_deg_per_100m, *b.r_err_deg_per_100m, 1e-6);
}

TEST(EvaluateTrajectory, PositionsOnlyEstimateHasNoRotationMetrics) {
  const auto gt = test::MakeLoopTrajectory(1500, 150.0);
  Trajectory est = gt;
  est.has_rotation = false;
  for (auto& p : est.poses) {
    p.world_from_cam.rotation = Eigen::Quaterniond::Identity();
    p.world_from_cam.translation *= 0.25;  // monocular: unknown scale
  }
  EvaluationOptions options;
  options.alignment = Alignment::kSim3;
  const auto e = EvaluateTrajectory(gt, est, options);
  ASSERT_EQ(e.status, EvaluationStatus::kOk);
  EXPECT_FALSE(e.rotation_evaluated);
  EXPECT_NEAR(e.alignment.gt_from_est.scale, 4.0, 1e-9);
  EXPECT_LT(e.ate.rmse, 1e-9);
  ASSERT_TRUE(e.rpe && e.kitti);
  EXPECT_FALSE(e.rpe->rotation_deg);
  EXPECT_FALSE(e.kitti->r_err_deg_per_100m);
  EXPECT_LT(*e.kitti->t_err_pct, 1e-9);
}

TEST(EvaluateTrajectory, NoAssociation) {
  const auto gt = test::MakeLoopTrajectory(10);
  auto est = gt;
  for (auto& p : est.poses) p.timestamp += 100.0;
  const auto e = EvaluateTrajectory(gt, est, {});
  EXPECT_EQ(e.status, EvaluationStatus::kNoAssociation);
  EXPECT_EQ(e.ate.count, 0u);
}

}  // namespace
}  // namespace sparseloop
