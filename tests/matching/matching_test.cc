#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "sparseloop/matching/descriptor_matching.h"
#include "sparseloop/matching/geometric_verification.h"
#include "sparseloop/matching/sim3_solver.h"
#include "test_util.h"

namespace sparseloop {
namespace {

Descriptor Random(std::mt19937_64& rng) { return {rng(), rng(), rng(), rng()}; }
Descriptor FlipBits(Descriptor d, int bits, std::mt19937_64& rng) {
  for (int i = 0; i < bits; ++i) {
    const int b = static_cast<int>(rng() % 256);
    d[b / 64] ^= 1ull << (b % 64);
  }
  return d;
}

TEST(Matching, BruteForceOracle) {
  auto rng = test::SeededRng(11);
  std::vector<Descriptor> train(60), query;
  for (auto& d : train) d = Random(rng);
  for (int i = 0; i < 40; ++i) query.push_back(i % 2 ? FlipBits(train[i], 10, rng) : Random(rng));
  MatchOptions o;
  o.ratio = 1.0;
  o.mutual = false;
  o.max_distance = 256;
  const auto m = MatchDescriptors(query, train, o);
  ASSERT_EQ(m.size(), query.size());
  for (const auto& x : m) {
    int best = 1000;
    for (const auto& t : train) best = std::min(best, HammingDistance(query[x.query], t));
    EXPECT_EQ(x.distance, best);
    EXPECT_EQ(HammingDistance(query[x.query], train[x.train]), best);
  }
  // Default options keep exactly the planted (odd) matches: random pairs are ~128 bits apart.
  const auto good = MatchDescriptors(query, train, MatchOptions{});
  ASSERT_EQ(good.size(), 20u);
  for (const auto& x : good) {
    EXPECT_EQ(x.query % 2, 1);
    EXPECT_EQ(x.train, x.query);
  }
}

TEST(Matching, MutualAndRatio) {
  const Descriptor a{0, 0, 0, 0};
  const Descriptor b{1, 0, 0, 0};     // 1 bit from a
  const Descriptor c{0b11, 0, 0, 0};  // 2 bits from a
  MatchOptions o;
  o.ratio = 1.0;
  o.mutual = true;
  // Both a and b prefer train a; mutual keeps only query a.
  auto m = MatchDescriptors({a, b}, {a}, o);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].query, 0);
  // Ratio: best 1 vs second 2 -> 0.5 passes 0.9; equal distances fail.
  o.mutual = false;
  o.ratio = 0.9;
  EXPECT_EQ(MatchDescriptors({a}, {b, c}, o).size(), 1u);
  EXPECT_EQ(MatchDescriptors({b}, {a, Descriptor{0b11, 0, 0, 0}}, o).size(), 0u);
  EXPECT_TRUE(MatchDescriptors({}, {a}, o).empty());
  o.ratio = 0;
  EXPECT_THROW(o.Check(), std::invalid_argument);
}

Sim3d RandomSim3(std::mt19937_64& rng, double scale) {
  std::normal_distribution<double> n(0, 1);
  return Sim3d(scale, ExpSO3(Eigen::Vector3d(n(rng), n(rng), n(rng)) * 0.3),
               Eigen::Vector3d(n(rng), n(rng), n(rng)));
}

TEST(Sim3Solver, UmeyamaRecoversKnownTransform) {
  auto rng = test::SeededRng(12);
  const Sim3d truth = RandomSim3(rng, 2.5);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Eigen::Vector3d> src, dst;
  for (int i = 0; i < 10; ++i) {
    src.emplace_back(u(rng), u(rng), 4 + u(rng));
    dst.push_back(truth * src.back());
  }
  const auto est = UmeyamaSim3(src, dst);
  ASSERT_TRUE(est.has_value());
  EXPECT_NEAR(est->scale, 2.5, 1e-9);
  EXPECT_LT(RotationAngle(est->rotation, truth.rotation), 1e-9);
  EXPECT_LT((est->translation - truth.translation).norm(), 1e-9);
  const auto rigid = UmeyamaSim3(src, dst, false);
  ASSERT_TRUE(rigid.has_value());
  EXPECT_EQ(rigid->scale, 1.0);
  // Degenerate: collinear points, too few points.
  std::vector<Eigen::Vector3d> line = {{0, 0, 1}, {0, 0, 2}, {0, 0, 3}};
  EXPECT_FALSE(UmeyamaSim3(line, line).has_value());
  EXPECT_FALSE(UmeyamaSim3({src[0], src[1]}, {dst[0], dst[1]}).has_value());
}

// Synthetic two-view scene: points in front of both cameras, normalised observations.
struct Scene {
  KeyframeRecord query, match;
  std::vector<DescriptorMatch> matches;
  Rigid3d match_from_query;
};

Scene MakeScene(uint64_t seed, int n, int outliers, bool depths_query, bool depths_match,
                double scale_query = 1.0) {
  auto rng = test::SeededRng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  Scene s;
  s.match_from_query =
      Rigid3d(ExpSO3(Eigen::Vector3d(0.05, 0.3, -0.02)), Eigen::Vector3d(0.8, 0.1, 0.2));
  const Rigid3d query_from_match = s.match_from_query.Inverse();
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p_in_match(3 * u(rng), 2 * u(rng), 6 + 3 * u(rng));
    Eigen::Vector3d p_in_query = query_from_match * p_in_match;
    if (i >= n - outliers) p_in_query = Eigen::Vector3d(3 * u(rng), 2 * u(rng), 6 + 2 * u(rng));
    CompactKeypoint km, kq;
    km.x = float(p_in_match.x() / p_in_match.z());
    km.y = float(p_in_match.y() / p_in_match.z());
    kq.x = float(p_in_query.x() / p_in_query.z());
    kq.y = float(p_in_query.y() / p_in_query.z());
    s.match.keypoints.push_back(km);
    s.query.keypoints.push_back(kq);
    if (depths_match) s.match.depths.push_back(float(p_in_match.z()));
    if (depths_query) s.query.depths.push_back(float(p_in_query.z() / scale_query));
    s.matches.push_back({i, i, 10});
  }
  s.query.focal_px = s.match.focal_px = 500.0f;
  s.query.descriptors.resize(n);
  s.match.descriptors.resize(n);
  return s;
}

TEST(Verification, EssentialRecoversRelativePose) {
  const Scene s = MakeScene(21, 80, 20, false, false);
  const auto v = VerifyPair(s.query, s.match, s.matches, VerifyOptions{});
  ASSERT_TRUE(v.success);
  EXPECT_EQ(v.method, VerificationMethod::kEssential);
  EXPECT_EQ(v.pose_kind, RelativePoseKind::kSE3UnitTranslation);
  EXPECT_GE(v.inliers, 55);
  EXPECT_LE(v.inliers, 62);
  EXPECT_LT(RotationAngle(v.match_from_query.rotation, s.match_from_query.rotation),
            0.2 * M_PI / 180);
  EXPECT_NEAR(v.match_from_query.translation.norm(), 1.0, 1e-9);
  EXPECT_GT(v.match_from_query.translation.dot(s.match_from_query.translation.normalized()),
            std::cos(1.0 * M_PI / 180));
  // Deterministic: same seed, same answer.
  const auto again = VerifyPair(s.query, s.match, s.matches, VerifyOptions{});
  EXPECT_EQ(again.inliers, v.inliers);
  EXPECT_EQ(again.match_from_query.rotation.coeffs(), v.match_from_query.rotation.coeffs());
}

TEST(Verification, LocalOptimizationOption) {
  VerifyOptions o;
  o.local_optimization_rounds = -1;
  EXPECT_THROW(o.Check(), std::invalid_argument);
  // Without local optimisation the result is still a valid pose; with it (default) at least as
  // many inliers and a pose at least as close to the truth on this noiseless scene.
  const Scene s = MakeScene(26, 80, 20, false, false);
  o.local_optimization_rounds = 0;
  const auto plain = VerifyPair(s.query, s.match, s.matches, o);
  const auto lo = VerifyPair(s.query, s.match, s.matches, VerifyOptions{});
  ASSERT_TRUE(plain.success);
  ASSERT_TRUE(lo.success);
  EXPECT_GE(lo.inliers, plain.inliers);
  EXPECT_LT(RotationAngle(lo.match_from_query.rotation, s.match_from_query.rotation),
            0.2 * M_PI / 180);
}

TEST(Verification, RandomCorrespondencesFail) {
  Scene s = MakeScene(22, 60, 60, false, false);  // all outliers
  const auto v = VerifyPair(s.query, s.match, s.matches, VerifyOptions{});
  EXPECT_FALSE(v.success);
  EXPECT_LT(v.inliers, VerifyOptions{}.min_inliers);
}

TEST(Verification, FundamentalCountsInliersWithoutPose) {
  const Scene s = MakeScene(23, 80, 20, false, false);
  VerifyOptions o;
  o.use_fundamental = true;
  const auto v = VerifyPair(s.query, s.match, s.matches, o);
  ASSERT_TRUE(v.success);
  EXPECT_EQ(v.pose_kind, RelativePoseKind::kNone);
  EXPECT_GE(v.inliers, 58);
}

TEST(Verification, PnPWithMatchDepths) {
  const Scene s = MakeScene(24, 60, 10, false, true);
  const auto v = VerifyPair(s.query, s.match, s.matches, VerifyOptions{});
  ASSERT_TRUE(v.success);
  EXPECT_EQ(v.method, VerificationMethod::kPnP);
  EXPECT_EQ(v.pose_kind, RelativePoseKind::kSE3Metric);
  EXPECT_LT(RotationAngle(v.match_from_query.rotation, s.match_from_query.rotation), 1e-3);
  EXPECT_LT((v.match_from_query.translation - s.match_from_query.translation).norm(), 1e-2);
}

TEST(Verification, Sim3WithDepthsOnBothSidesCarriesScale) {
  // Query depths in a different unit (scale drift): p_in_match = 2 * R p_query_units + t.
  const Scene s = MakeScene(25, 60, 10, true, true, 0.5);
  const auto v = VerifyPair(s.query, s.match, s.matches, VerifyOptions{});
  ASSERT_TRUE(v.success);
  EXPECT_EQ(v.method, VerificationMethod::kSim3);
  EXPECT_EQ(v.pose_kind, RelativePoseKind::kSim3);
  EXPECT_NEAR(v.match_from_query.scale, 0.5, 1e-3);
  EXPECT_LT(RotationAngle(v.match_from_query.rotation, s.match_from_query.rotation), 1e-3);
  EXPECT_GE(v.inliers, 48);
  EXPECT_LE(v.inliers, 52);
}

// Depths on both sides, but the query's are wrong (a bad depth map; here each multiplied by a
// random factor in [0.5, 2]): no 3-point Sim(3) verifies, and the detector falls back to PnP of
// the match's 3D points against the query's observations, which recovers the pose. The same
// scene with the query's depths intact takes the Sim(3) path (previous test).
TEST(Verification, BadDepthsOnOneSideFallBackToPnP) {
  Scene s = MakeScene(27, 60, 10, true, true);
  auto rng = test::SeededRng(28);
  std::uniform_real_distribution<double> log_factor(std::log(0.5), std::log(2.0));
  for (float& d : s.query.depths) d *= static_cast<float>(std::exp(log_factor(rng)));
  const auto v = VerifyPair(s.query, s.match, s.matches, VerifyOptions{});
  ASSERT_TRUE(v.success);
  EXPECT_EQ(v.method, VerificationMethod::kPnP);
  EXPECT_EQ(v.pose_kind, RelativePoseKind::kSE3Metric);
  EXPECT_GE(v.inliers, 48);
  EXPECT_LT(RotationAngle(v.match_from_query.rotation, s.match_from_query.rotation), 1e-3);
  EXPECT_LT((v.match_from_query.translation - s.match_from_query.translation).norm(), 1e-2);
}

}  // namespace
}  // namespace sparseloop
