// TriangulateFromNeighbours against the ground truth of synthetic scenes: exact depths from exact
// observations (any raw scale), and each rejection rule (reprojection, parallax, cheirality).
#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "sparseloop/core/rigid3.h"
#include "sparseloop/matching/triangulation.h"
#include "test_util.h"

namespace sparseloop {
namespace {

Descriptor RandomDescriptor(std::mt19937_64& rng) { return {rng(), rng(), rng(), rng()}; }

CompactKeypoint Project(const Eigen::Vector3d& p) {
  CompactKeypoint k;
  k.x = static_cast<float>(p.x() / p.z());
  k.y = static_cast<float>(p.y() / p.z());
  return k;
}

KeyframeRecord MakeRecord(int64_t id, const Sim3d& world_from_cam) {
  KeyframeRecord r;
  r.id = id;
  r.has_pose = true;
  r.world_from_cam = world_from_cam;
  r.focal_px = 500.0f;
  return r;
}

// Points 4-10 units in front of `a`; `b` (and `c`) observe the same points with the same
// descriptors. Returns the true depths in a's frame.
struct Views {
  KeyframeRecord a, b, c;
  std::vector<double> depth_in_a;
};

Views MakeViews(uint64_t seed, int n, const Sim3d& world_from_a, const Sim3d& a_from_b,
                const Sim3d& a_from_c) {
  auto rng = test::SeededRng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  Views v{MakeRecord(0, world_from_a),
          MakeRecord(1, world_from_a * a_from_b),
          MakeRecord(2, world_from_a * a_from_c),
          {}};
  const Sim3d b_from_a = a_from_b.Inverse(), c_from_a = a_from_c.Inverse();
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p(2 * u(rng), 1.5 * u(rng), 7 + 3 * u(rng));
    const Descriptor d = RandomDescriptor(rng);
    v.a.keypoints.push_back(Project(p));
    v.b.keypoints.push_back(Project(b_from_a * p));
    v.c.keypoints.push_back(Project(c_from_a * p));
    v.a.descriptors.push_back(d);
    v.b.descriptors.push_back(d);
    v.c.descriptors.push_back(d);
    v.depth_in_a.push_back(p.z());
  }
  return v;
}

const Sim3d kWorldFromA(2.5, ExpSO3(Eigen::Vector3d(0.1, -0.4, 0.2)), Eigen::Vector3d(3, -1, 2));

TEST(Triangulation, ExactObservationsGiveTheTrueDepthsInTheRecordFrame) {
  // b 1 unit to the side of a (about 8 deg of parallax at 7 units), rotated a little; the raw
  // world has scale 2.5, so the depths must come out in a's camera units, not world units.
  const Sim3d a_from_b(1.0, ExpSO3(Eigen::Vector3d(0.0, 0.05, 0.0)), Eigen::Vector3d(1, 0, 0));
  const Views v = MakeViews(3, 60, kWorldFromA, a_from_b, a_from_b);
  const TriangulationResult r = TriangulateFromNeighbours(v.a, {&v.b}, TriangulationOptions{});
  ASSERT_EQ(r.depths.size(), v.a.size());
  EXPECT_EQ(r.triangulated, 60);
  for (size_t i = 0; i < r.depths.size(); ++i)
    EXPECT_NEAR(r.depths[i], v.depth_in_a[i], 1e-4 * v.depth_in_a[i]) << i;
}

TEST(Triangulation, NeighbourWithItsOwnScaleIsHandled) {
  // A Sim(3) raw pose per keyframe (monocular scale drift): b's camera units are 0.8 of a's.
  const Sim3d a_from_b(0.8, ExpSO3(Eigen::Vector3d(0.02, 0.0, 0.0)), Eigen::Vector3d(0.9, 0.2, 0));
  const Views v = MakeViews(4, 40, kWorldFromA, a_from_b, a_from_b);
  const TriangulationResult r = TriangulateFromNeighbours(v.a, {&v.b}, TriangulationOptions{});
  EXPECT_EQ(r.triangulated, 40);
  for (size_t i = 0; i < r.depths.size(); ++i)
    EXPECT_NEAR(r.depths[i], v.depth_in_a[i], 1e-4 * v.depth_in_a[i]) << i;
}

TEST(Triangulation, WrongMatchesFailTheReprojectionCheck) {
  const Sim3d a_from_b(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0));
  Views v = MakeViews(5, 40, kWorldFromA, a_from_b, a_from_b);
  // Ten keypoints of b moved 5 px vertically (no epipolar line is vertical here): outliers.
  for (int i = 0; i < 10; ++i) v.b.keypoints[i].y += 5.0f / 500.0f;
  const TriangulationResult r = TriangulateFromNeighbours(v.a, {&v.b}, TriangulationOptions{});
  EXPECT_EQ(r.triangulated, 30);
  for (int i = 0; i < 10; ++i) EXPECT_LE(r.depths[i], 0.0f) << i;
  // A looser reprojection bound lets them in.
  TriangulationOptions loose;
  loose.max_reprojection_px = 10.0;
  EXPECT_EQ(TriangulateFromNeighbours(v.a, {&v.b}, loose).triangulated, 40);
}

TEST(Triangulation, TooLittleParallaxOrNoBaselineGivesNoDepth) {
  // 0.1 units of baseline at 7 units: < 1 deg of parallax, under the 2 deg default.
  const Sim3d small(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.1, 0, 0));
  const Views v = MakeViews(6, 30, kWorldFromA, small, small);
  EXPECT_EQ(TriangulateFromNeighbours(v.a, {&v.b}, TriangulationOptions{}).triangulated, 0);
  TriangulationOptions any;
  any.min_parallax_deg = 0.0;
  EXPECT_EQ(TriangulateFromNeighbours(v.a, {&v.b}, any).triangulated, 30);
  // Pure rotation: nothing to triangulate.
  const Sim3d rot(1.0, ExpSO3(Eigen::Vector3d(0, 0.1, 0)), Eigen::Vector3d::Zero());
  const Views w = MakeViews(7, 30, kWorldFromA, rot, rot);
  EXPECT_EQ(TriangulateFromNeighbours(w.a, {&w.b}, any).triangulated, 0);
}

TEST(Triangulation, PointsBehindACameraAreRejected) {
  // The neighbour's pose is mirrored through a (the raw pose says b is behind where it is): every
  // ray pair then meets behind one of the cameras.
  const Sim3d a_from_b(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0));
  Views v = MakeViews(8, 30, kWorldFromA, a_from_b, a_from_b);
  v.b.world_from_cam =
      kWorldFromA * Sim3d(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(-1, 0, 0));
  TriangulationOptions any;
  any.min_parallax_deg = 0.0;
  EXPECT_EQ(TriangulateFromNeighbours(v.a, {&v.b}, any).triangulated, 0);
}

TEST(Triangulation, LargestParallaxNeighbourWinsAndPoselessOnesAreSkipped) {
  // b: 1 unit baseline, exact; c: 3 units baseline but its observations carry a 1 px error.
  // Both pass the checks; the depth must be c's (larger parallax), i.e. not exact.
  const Sim3d a_from_b(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0));
  const Sim3d a_from_c(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(3, 0, 0));
  Views v = MakeViews(9, 20, kWorldFromA, a_from_b, a_from_c);
  for (auto& k : v.c.keypoints) k.x += 1.0f / 500.0f;
  const TriangulationResult both = TriangulateFromNeighbours(v.a, {&v.b, &v.c}, {});
  const TriangulationResult only_b = TriangulateFromNeighbours(v.a, {&v.b}, {});
  ASSERT_EQ(both.triangulated, 20);
  for (size_t i = 0; i < v.a.size(); ++i) {
    EXPECT_NEAR(only_b.depths[i], v.depth_in_a[i], 1e-4 * v.depth_in_a[i]);
    EXPECT_GT(std::abs(both.depths[i] - v.depth_in_a[i]), 1e-3) << "c's depth, not b's: " << i;
    EXPECT_LT(std::abs(both.depths[i] - v.depth_in_a[i]), 0.1 * v.depth_in_a[i]);
  }
  KeyframeRecord no_pose = v.b;
  no_pose.has_pose = false;
  EXPECT_EQ(TriangulateFromNeighbours(v.a, {&no_pose, nullptr}, {}).triangulated, 0);
}

TEST(Triangulation, BadInputIsRejectedWithAClearError) {
  const Views v = MakeViews(10, 5, kWorldFromA, Sim3d(), Sim3d());
  KeyframeRecord no_pose = v.a;
  no_pose.has_pose = false;
  EXPECT_THROW(TriangulateFromNeighbours(no_pose, {&v.b}, {}), std::invalid_argument);
  TriangulationOptions bad;
  bad.max_reprojection_px = 0;
  EXPECT_THROW(TriangulateFromNeighbours(v.a, {&v.b}, bad), std::invalid_argument);
  bad = {};
  bad.min_parallax_deg = 90;
  EXPECT_THROW(bad.Check(), std::invalid_argument);
  bad = {};
  bad.min_image_pose_inliers = 7;
  EXPECT_THROW(bad.Check(), std::invalid_argument);
  bad = {};
  bad.image_pose_prior_deg = 0;
  EXPECT_THROW(bad.Check(), std::invalid_argument);
}

// The odometry's relative pose of b drifted by `bias_deg` about one camera axis of b (x pitch,
// y yaw, z roll): what a monocular vSLAM without an IMU hands over between neighbours.
Sim3d Drifted(const Sim3d& world_from_b, int axis, double bias_deg) {
  Sim3d out = world_from_b;
  out.rotation =
      world_from_b.rotation * ExpSO3(bias_deg * M_PI / 180.0 * Eigen::Vector3d::Unit(axis));
  return out;
}

double RotationErrorDeg(const Sim3d& a, const Sim3d& b) {
  return a.rotation.angularDistance(b.rotation) * 180.0 / M_PI;
}

// Median relative depth error of the triangulated keypoints.
double MedianDepthError(const TriangulationResult& r, const std::vector<double>& truth) {
  std::vector<double> e;
  for (size_t i = 0; i < r.depths.size(); ++i)
    if (r.depths[i] > 0) e.push_back(std::abs(r.depths[i] - truth[i]) / truth[i]);
  if (e.empty()) return 1.0;
  std::nth_element(e.begin(), e.begin() + e.size() / 2, e.end());
  return e[e.size() / 2];
}

TEST(RelativePoseFromImages, RemovesTheRawRotationDriftAboutEveryAxis) {
  // b 1 unit to the side (8 deg of parallax), observations with 0.5 px noise; the raw pose of b
  // rotated by 1 deg about each camera axis in turn. The images fix roll and pitch; yaw trades
  // against the sideways baseline in two views, and the prior keeps it no worse than raw.
  const Sim3d a_from_b(1.0, ExpSO3(Eigen::Vector3d(0.0, 0.05, 0.0)), Eigen::Vector3d(1, 0, 0));
  for (int axis = 0; axis < 3; ++axis) {
    SCOPED_TRACE("axis " + std::to_string(axis));
    Views v = MakeViews(20 + axis, 80, kWorldFromA, a_from_b, a_from_b);
    auto rng = test::SeededRng(30 + axis);
    std::normal_distribution<float> noise(0.0f, 0.5f / 500.0f);
    for (CompactKeypoint& k : v.b.keypoints) {
      k.x += noise(rng);
      k.y += noise(rng);
    }
    const Sim3d exact = v.b.world_from_cam.Inverse() * v.a.world_from_cam;
    v.b.world_from_cam = Drifted(v.b.world_from_cam, axis, 1.0);
    const Sim3d raw = v.b.world_from_cam.Inverse() * v.a.world_from_cam;
    std::vector<DescriptorMatch> matches;
    for (int i = 0; i < 80; ++i) matches.push_back({i, i, 0});
    std::vector<int> inliers;
    const std::optional<Sim3d> refined =
        RelativePoseFromImages(v.a, v.b, matches, raw, 15, 0.25, &inliers);
    ASSERT_TRUE(refined.has_value());
    EXPECT_GE(inliers.size(), 70u);
    EXPECT_NEAR(RotationErrorDeg(raw, exact), 1.0, 1e-6);
    // Roll and pitch: most of the drift removed; yaw: not worse than the raw pose.
    EXPECT_LT(RotationErrorDeg(*refined, exact), axis == 1 ? 1.0 : 0.3);
    // The baseline length (and the raw scale) come from the raw pose.
    EXPECT_NEAR(refined->translation.norm(), raw.translation.norm(), 1e-9);
    EXPECT_EQ(refined->scale, raw.scale);
  }
}

TEST(RelativePoseFromImages, TriangulationWithADriftedNeighbourRecoversTheDepths) {
  // The same scene, b's raw pose rolled 1 deg: with the raw relative pose most points fail the
  // 2 px reprojection check or come out bent; with the pose from the images they come out right.
  const Sim3d a_from_b(1.0, ExpSO3(Eigen::Vector3d(0.0, 0.05, 0.0)), Eigen::Vector3d(1, 0, 0));
  Views v = MakeViews(40, 80, kWorldFromA, a_from_b, a_from_b);
  v.b.world_from_cam = Drifted(v.b.world_from_cam, 2, 1.0);
  TriangulationOptions raw_only;
  raw_only.min_image_pose_inliers = 0;
  const TriangulationResult raw = TriangulateFromNeighbours(v.a, {&v.b}, raw_only);
  const TriangulationResult images = TriangulateFromNeighbours(v.a, {&v.b}, {});
  EXPECT_EQ(raw.raw_poses, 1);
  EXPECT_EQ(raw.image_poses, 0);
  EXPECT_EQ(images.image_poses, 1);
  EXPECT_EQ(images.raw_poses, 0);
  EXPECT_GE(images.triangulated, 75);
  EXPECT_LT(MedianDepthError(images, v.depth_in_a), 0.01);
  EXPECT_LT(raw.triangulated, images.triangulated * 2 / 3);
  EXPECT_GT(MedianDepthError(raw, v.depth_in_a), 3 * MedianDepthError(images, v.depth_in_a))
      << MedianDepthError(raw, v.depth_in_a);
}

TEST(RelativePoseFromImages, WrongOrTooFewMatchesKeepTheRawPose) {
  const Sim3d a_from_b(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0));
  Views v = MakeViews(50, 60, kWorldFromA, a_from_b, a_from_b);
  const Sim3d raw = v.b.world_from_cam.Inverse() * v.a.world_from_cam;
  std::vector<DescriptorMatch> matches;
  for (int i = 0; i < 60; ++i) matches.push_back({i, (i * 7 + 3) % 60, 0});  // shuffled
  EXPECT_FALSE(RelativePoseFromImages(v.a, v.b, matches, raw, 15, 0.25).has_value());
  matches.clear();
  for (int i = 0; i < 10; ++i) matches.push_back({i, i, 0});  // right, but fewer than 15
  EXPECT_FALSE(RelativePoseFromImages(v.a, v.b, matches, raw, 15, 0.25).has_value());
  EXPECT_TRUE(RelativePoseFromImages(v.a, v.b, matches, raw, 8, 0.25).has_value());
  // No baseline: nothing to take a length from.
  EXPECT_FALSE(RelativePoseFromImages(v.a, v.b, matches, Sim3d(), 8, 0.25).has_value());
  // Shuffled matches through the triangulation: the raw pose is used and counted.
  for (size_t i = 0; i < v.b.descriptors.size(); ++i)
    v.b.descriptors[i] = v.a.descriptors[(i * 7 + 3) % 60];
  const TriangulationResult r = TriangulateFromNeighbours(v.a, {&v.b}, {});
  EXPECT_EQ(r.raw_poses, 1);
  EXPECT_EQ(r.image_poses, 0);
}

TEST(RelativePoseCache, RefinesEachPairOnceAndGivesTheReverseAsTheInverse) {
  const Sim3d a_from_b(1.0, ExpSO3(Eigen::Vector3d(0.0, 0.05, 0.0)), Eigen::Vector3d(1, 0, 0));
  Views v = MakeViews(60, 80, kWorldFromA, a_from_b, a_from_b);
  v.b.world_from_cam = Drifted(v.b.world_from_cam, 2, 1.0);
  std::vector<DescriptorMatch> ab, ba;
  for (int i = 0; i < 80; ++i) {
    ab.push_back({i, i, 0});
    ba.push_back({i, i, 0});
  }
  const TriangulationOptions options;
  const Sim3d raw_b_from_a = v.b.world_from_cam.Inverse() * v.a.world_from_cam;
  const std::optional<Sim3d> direct = RelativePoseFromImages(
      v.a, v.b, ab, raw_b_from_a, options.min_image_pose_inliers, options.image_pose_prior_deg);
  ASSERT_TRUE(direct.has_value());
  RelativePoseCache cache;
  const std::optional<Sim3d> first = cache.Get(v.a, v.b, ab, raw_b_from_a, options);
  const std::optional<Sim3d> reverse = cache.Get(v.b, v.a, ba, raw_b_from_a.Inverse(), options);
  EXPECT_EQ(cache.size(), 1u);
  ASSERT_TRUE(first.has_value() && reverse.has_value());
  const Sim3d identity = *reverse * *first;
  EXPECT_LT(identity.rotation.angularDistance(Eigen::Quaterniond::Identity()), 1e-9);
  EXPECT_LT(identity.translation.norm(), 1e-9);
  EXPECT_LT(first->rotation.angularDistance(direct->rotation), 1e-9);
  EXPECT_LT((first->translation - direct->translation).norm(), 1e-9);
  // Through the triangulation: the same depths with the cache as without.
  const TriangulationResult plain = TriangulateFromNeighbours(v.a, {&v.b}, options);
  const TriangulationResult cached = TriangulateFromNeighbours(v.a, {&v.b}, options, &cache);
  EXPECT_EQ(cache.size(), 1u);
  EXPECT_EQ(cached.image_poses, 1);
  ASSERT_EQ(cached.depths.size(), plain.depths.size());
  for (size_t i = 0; i < plain.depths.size(); ++i)
    EXPECT_NEAR(cached.depths[i], plain.depths[i], 1e-5f * std::max(1.0f, plain.depths[i])) << i;
  cache.Clear();
  EXPECT_EQ(cache.size(), 0u);
}

}  // namespace
}  // namespace sparseloop
