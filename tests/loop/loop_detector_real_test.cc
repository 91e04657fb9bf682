// The detector on real data with ONE default parameter set (the acceptance checks).
#include <cmath>
#include <cstdio>
#include <set>

#include <gtest/gtest.h>

#include "castle_input.h"
#include "euroc_pairs.h"
#include "real_data.h"
#include "sparseloop/loop/loop_detector.h"
#include "sparseloop/matching/descriptor_matching.h"
#include "sparseloop/matching/geometric_verification.h"
#include "test_util.h"

namespace sparseloop {
namespace {

double Deg(double rad) { return rad * 180.0 / M_PI; }
double AngleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return Deg(std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)));
}

struct CastleRun {
  std::vector<test::Frame> frames;
  std::vector<LoopResult> loops;
};

// Views 0001..0029 in order, GT poses as raw poses.
CastleRun RunCastle(const LoopDetector::Options& options) {
  CastleRun r;
  r.frames = test::LoadCastle();
  LoopDetector detector(options);
  for (size_t i = 0; i < r.frames.size(); ++i) {
    const KeyframeInput in = test::CastleKeyframe(r.frames, i);
    const LoopResult res = detector.Process(in);
    std::printf("view %02lld: %-24s match=%lld matches=%d inliers=%d prior_err=%.1f\n",
                (long long)in.id, ToString(res.status), (long long)res.match_id, res.matches,
                res.inliers, res.rotation_error_vs_prior_deg);
    if (res.detected()) r.loops.push_back(res);
  }
  return r;
}

// DEFAULT options; run once per test binary.
const CastleRun& Castle() {
  static const CastleRun run = RunCastle(LoopDetector::Options{});
  return run;
}

TEST(LoopDetectorReal, CastleRingClosesWithDefaults) {
  SL_REQUIRE_DATA("castle_p30_768");
  const CastleRun& run = Castle();
  ASSERT_EQ(run.loops.size(), 1u) << "exactly the ring closure, no false loop";
  const LoopResult& loop = run.loops[0];
  EXPECT_EQ(loop.query_id, 29);
  EXPECT_TRUE(loop.match_id == 1 || loop.match_id == 2) << loop.match_id;
  // Monocular (no depths): the essential matrix detects, PnP against the local map triangulated
  // around the match (raw = GT poses here) gives the pose, with its length.
  ASSERT_EQ(loop.pose_kind, RelativePoseKind::kSE3Metric);
  EXPECT_EQ(loop.method, VerificationMethod::kPnP);
  EXPECT_GE(loop.local_map_inliers, 30);
  const Rigid3d gt =
      run.frames[loop.match_id - 1].world_from_cam.Inverse() * run.frames[28].world_from_cam;
  const double rot_err = Deg(RotationAngle(gt.rotation, loop.match_from_query.rotation));
  const double dir_err = AngleBetween(gt.translation, loop.match_from_query.translation);
  const double centre_err = (loop.match_from_query.translation - gt.translation).norm();
  std::printf(
      "castle 29->%lld: inliers %d, local map %d points / %d inliers, rotation error %.2f deg, "
      "direction error %.2f deg, translation %.3f m (GT %.3f m), error %.3f m\n",
      (long long)loop.match_id, loop.inliers, loop.local_map_points, loop.local_map_inliers,
      rot_err, dir_err, loop.match_from_query.translation.norm(), gt.translation.norm(),
      centre_err);
  EXPECT_LT(rot_err, 1.0);
  EXPECT_LT(dir_err, 5.0);  // the target (two-view only: 18.5 deg, docs/DETECTOR.md)
  EXPECT_LT(centre_err, 0.05 * gt.translation.norm() + 0.05);
}

// The observation behind small K: with 50 response-ranked features per view the true
// loop 29-01 has clearly more essential-matrix inliers than the false pairs 29-15 and 20-05
// (about 23 vs <= 8; every ranking and K: bench/detector_accuracy, castle_pairs).
TEST(LoopDetectorReal, CastleTrueLoopOutscoresFalsePairsAtK50) {
  SL_REQUIRE_DATA("castle_p30_768");
  const std::vector<test::Frame> frames = test::LoadCastle();
  FeatureOptions fo;
  fo.ranking = FeatureRanking::kResponse;
  fo.max_features = 50;
  const auto inliers = [&](int q, int m) {  // view numbers; frames[i] is view i + 1
    KeyframeRecord rq, rm;
    for (auto [view, record] : {std::pair{q, &rq}, std::pair{m, &rm}}) {
      FeatureInput in;
      in.image = &frames[view - 1].image;
      in.intrinsics = &frames[view - 1].intrinsics;
      ExtractInformativeFeatures(in, fo, record);
    }
    VerifyOptions vo;
    vo.min_inliers = 5;
    return VerifyPair(rq, rm, MatchDescriptors(rq.descriptors, rm.descriptors, MatchOptions{}), vo)
        .inliers;
  };
  const int true_loop = inliers(29, 1);
  const int false_pairs = std::max(inliers(29, 15), inliers(20, 5));
  EXPECT_GE(true_loop, 15);
  EXPECT_GT(true_loop, 2 * false_pairs) << true_loop << " vs " << false_pairs;
}

// The two-view estimate alone (local map off): the rotation target holds, the direction
// one does not (a 0.8 m baseline to 29 -> 01 against a facade 10-20 m away; the Huber-Sampson
// optimum of its K = 300 inliers is itself 18 deg from the GT). Kept as the measured baseline of
// what the local map buys.
TEST(LoopDetectorReal, CastleTwoViewOnlyRotationAccurateDirectionNot) {
  SL_REQUIRE_DATA("castle_p30_768");
  LoopDetector::Options o;
  o.local_map.enabled = false;
  const CastleRun run = RunCastle(o);
  ASSERT_EQ(run.loops.size(), 1u);
  const LoopResult& loop = run.loops[0];
  ASSERT_EQ(loop.pose_kind, RelativePoseKind::kSE3UnitTranslation);
  const Rigid3d gt =
      run.frames[loop.match_id - 1].world_from_cam.Inverse() * run.frames[28].world_from_cam;
  const double rot_err = Deg(RotationAngle(gt.rotation, loop.match_from_query.rotation));
  const double dir_err = AngleBetween(gt.translation, loop.match_from_query.translation);
  std::printf("castle two-view 29->%lld: inliers %d, rotation error %.2f deg, direction %.2f deg\n",
              (long long)loop.match_id, loop.inliers, rot_err, dir_err);
  EXPECT_EQ(loop.match_id, 1);
  EXPECT_LT(rot_err, 1.0);
  EXPECT_GT(dir_err, 5.0);
  EXPECT_LT(dir_err, 25.0);
}

class KittiNoLoop : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!std::filesystem::exists(test::DataDir() / "kitti07_first160")) return;
    images_ = new std::vector<cv::Mat>(test::LoadKittiImages(160));
    poses_ = new std::vector<Rigid3d>(
        test::ReadKittiPoses(test::DataDir() / "kitti07_first160" / "07_first160_DERIVED.txt"));
  }
  static void TearDownTestSuite() {
    delete images_;
    delete poses_;
    images_ = nullptr;
    poses_ = nullptr;
  }
  // `poses` empty: no poses, global search (default options otherwise).
  static int CountLoops(const std::vector<Sim3d>& poses, LoopDetector::Options options = {}) {
    if (poses.empty()) options.search.strategy = SearchStrategy::kGlobal;
    LoopDetector detector(options);
    int loops = 0;
    for (size_t i = 0; i < images_->size(); ++i) {
      KeyframeInput in;
      in.id = static_cast<int64_t>(i);
      in.timestamp = static_cast<double>(in.id);  // keyframe timestamps must increase
      in.image = (*images_)[i];
      in.intrinsics = test::KittiIntrinsics();
      if (!poses.empty()) in.world_from_cam = poses[i];
      const LoopResult r = detector.Process(in);
      if (r.detected()) {
        ++loops;
        std::printf("false loop %lld -> %lld inliers %d\n", (long long)r.query_id,
                    (long long)r.match_id, r.inliers);
      }
    }
    return loops;
  }
  static std::vector<cv::Mat>* images_;
  static std::vector<Rigid3d>* poses_;
};
std::vector<cv::Mat>* KittiNoLoop::images_ = nullptr;
std::vector<Rigid3d>* KittiNoLoop::poses_ = nullptr;

TEST_F(KittiNoLoop, ZeroLoopsWithGtPoses) {
  SL_REQUIRE_DATA("kitti07_first160");
  ASSERT_EQ(poses_->size(), 160u);
  std::vector<Sim3d> poses;
  for (const auto& p : *poses_) poses.emplace_back(p);
  EXPECT_EQ(CountLoops(poses), 0);
}

TEST_F(KittiNoLoop, ZeroLoopsWithDriftedPoses) {
  SL_REQUIRE_DATA("kitti07_first160");
  ASSERT_EQ(poses_->size(), 160u);
  // Monocular-like drift: a heading error growing 0.2 deg per frame about the vertical (camera
  // -y) axis and a scale drifting by 0.5 % per frame, integrated along the GT increments.
  std::vector<Sim3d> poses{Sim3d((*poses_)[0])};
  for (size_t i = 1; i < poses_->size(); ++i) {
    const Rigid3d step = (*poses_)[i - 1].Inverse() * (*poses_)[i];
    const double s = std::pow(1.005, double(i));
    Sim3d drift_step(1.0, ExpSO3(Eigen::Vector3d(0, 0.2 * M_PI / 180, 0)) * step.rotation,
                     s * step.translation);
    poses.push_back(poses.back() * drift_step);
  }
  EXPECT_EQ(CountLoops(poses), 0);
}

// Without poses: the keyframes that still share the scene with the query along the
// recent path are not loops. With the fixed exclude_recent alone the same drive gave 107 false
// loops (the road 11-25 keyframes back); the overlap walk (Options::overlap_gap) leaves 4, all at
// the inlier floor (24-25 of 300: 36 -> 24, 55 -> 38, 109 -> 61, 155 -> 135); the continuity
// check (a keyframe 1/2 or 3/4 of the way verifies as well) removes those: zero, the target.
TEST_F(KittiNoLoop, NearTimeLoopsWithoutPosesAreExcluded) {
  SL_REQUIRE_DATA("kitti07_first160");
  EXPECT_EQ(CountLoops({}), 0);
}

// The same drive at a small K (K = 15 / 20 asymmetric, weak pairs, no poses). A
// stored record of 15-20 features cannot reach the walk's floor (3 x 8 matches), so without the
// buffer of recent extractions (Options::overlap_features) the walk ends at once and the road
// 11-19 keyframes ahead comes back as loops (4 / 7 without weak pairs, 11 / 16 with them:
// geometrically right, 12-16 m straight ahead, but no revisit). With it: none.
TEST_F(KittiNoLoop, NearTimeLoopsAtSmallKAreExcluded) {
  SL_REQUIRE_DATA("kitti07_first160");
  for (const int k : {15, 20}) {
    SCOPED_TRACE(k);
    LoopDetector::Options options;
    options.features.max_features = k;
    options.asymmetric_matching = true;
    options.weak_pairs = true;
    EXPECT_EQ(CountLoops({}, options), 0);
    if (k == 20) {  // the premise: without the buffer the walk lets them through
      options.overlap_features = 0;
      EXPECT_GE(CountLoops({}, options), 5);
    }
  }
}

// EuRoC pairs: tests/support/euroc_pairs.h (shared with bench/detector_accuracy).
test::EurocPairResult RunEurocPair(int pair, bool stereo = false) {
  const test::EurocPairResult r =
      test::RunEurocPair(test::DataDir() / "euroc_loop_pairs", pair, stereo);
  std::printf(
      "euroc pair (%d,%d)%s: %s, %s, inliers %d matches %d rotation error %.2f deg, translation "
      "error %.3f m (baseline %.3f m)\n",
      2 * pair, 2 * pair + 1, stereo ? " stereo depths" : "", ToString(r.result.status),
      ToString(r.result.method), r.result.inliers, r.result.matches, r.rotation_error_deg,
      r.translation_error_m, r.baseline_m);
  return r;
}

TEST(LoopDetectorReal, EurocPair01Verified) {
  SL_REQUIRE_DATA("euroc_loop_pairs");
  const test::EurocPairResult r = RunEurocPair(0);
  ASSERT_TRUE(r.result.detected()) << ToString(r.result.status);
  EXPECT_EQ(r.result.match_id, 0);
  EXPECT_LT(r.rotation_error_deg, 3.0);
}

TEST(LoopDetectorReal, EurocPair23PassesGeometricVerification) {
  SL_REQUIRE_DATA("euroc_loop_pairs");
  const test::EurocPairResult r = RunEurocPair(1);
  EXPECT_EQ(r.result.match_id, 2);
  EXPECT_GE(r.result.inliers, LoopDetector::Options{}.EffectiveMinInliers());
}

// Both pairs with the stereo depths a stereo vSLAM maps (the pairs come from Kimera-VIO's
// loop-closure test, a stereo VIO): verified from 3D (Sim(3) 3D-3D, or PnP when that does not
// verify), rotation < 3 deg from the GT (the target's bound) and translation within 15 cm.
// Reached at K = 300: (0,1) 2.27 deg / 0.11 m, (2,3) 0.65 deg / 0.05 m. Pair (2,3) is the one
// monocular two-view geometry gets wrong (next test); with depths it is the accurate one.
TEST(LoopDetectorReal, EurocPairsWithStereoDepthsVerifiedAndAccurate) {
  SL_REQUIRE_DATA("euroc_loop_pairs");
  for (int pair : {0, 1}) {
    SCOPED_TRACE(pair);
    const test::EurocPairResult r = RunEurocPair(pair, /*stereo=*/true);
    ASSERT_TRUE(r.result.detected()) << ToString(r.result.status);
    EXPECT_EQ(r.result.match_id, 2 * pair);
    EXPECT_TRUE(r.result.method == VerificationMethod::kSim3 ||
                r.result.method == VerificationMethod::kPnP)
        << ToString(r.result.method);
    EXPECT_LT(r.rotation_error_deg, 3.0);
    EXPECT_GE(r.translation_error_m, 0.0);
    EXPECT_LT(r.translation_error_m, 0.15);
    EXPECT_NEAR(r.result.match_from_query.scale, 1.0, 0.1);  // both depth maps are metric
  }
}

// Monocular pair (2,3): the lowest-cost essential-matrix pose is ~21 deg off the GT (39 of 77
// matches inliers at K = 300) and the pose-prior check rejects it; the scene is near-planar (a
// homography explains 28 of the matches) and one of the homography's decompositions is 2.4 deg
// from the GT with 33 essential inliers (Options::planar_alternatives). The GT is right: the
// stereo test above recovers it to 0.65 deg, and an independent OpenCV check (ORB 4000) gives
// 4.7-13.7 deg for the essential matrix but 2.1 deg for the homography (docs/DETECTOR.md).
TEST(LoopDetectorReal, EurocPair23DetectedByPlanarAlternative) {
  SL_REQUIRE_DATA("euroc_loop_pairs");
  const test::EurocPairResult r = RunEurocPair(1);
  ASSERT_TRUE(r.result.detected()) << ToString(r.result.status);
  EXPECT_EQ(r.result.match_id, 2);
  EXPECT_TRUE(r.result.planar_alternative);
  EXPECT_EQ(r.result.pose_kind, RelativePoseKind::kSE3UnitTranslation);
  EXPECT_LT(r.rotation_error_deg, 3.0);
  EXPECT_GE(r.result.inliers, LoopDetector::Options{}.EffectiveMinInliers());
  // Without the alternatives the lowest-cost model is what the prior sees, and rejects.
  const test::EurocPairResult off =
      test::RunEurocPair(test::DataDir() / "euroc_loop_pairs", 1, false, false);
  EXPECT_EQ(off.result.status, LoopStatus::kRejectedByConsistency);
  EXPECT_FALSE(off.result.planar_alternative);
  EXPECT_GT(off.rotation_error_deg, 10.0);
  // Pair (0,1) is not planar-ambiguous: its lowest-cost model stands.
  EXPECT_FALSE(RunEurocPair(0).result.planar_alternative);
}

}  // namespace
}  // namespace sparseloop
