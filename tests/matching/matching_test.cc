#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdio>
#include <random>
#include <set>
#include <span>

#include <gtest/gtest.h>

#include "matching/verification_internal.h"
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

// The blocked MatchDescriptors (distances of 16 query rows first, then row and column minima)
// against the one-pass reference it replaced, on sets with many ties (descriptors of 12 random
// bits, distances mostly 0-24): the same matches, the same tie-breaking (first index wins), for
// row counts below, at and above the block of 16, with and without the ratio and mutual tests.
TEST(Matching, BlockedMatchingEqualsTheOnePassReference) {
  const auto reference = [](const std::vector<Descriptor>& query,
                            const std::vector<Descriptor>& train, const MatchOptions& o) {
    const int nq = static_cast<int>(query.size()), nt = static_cast<int>(train.size());
    std::vector<int> best_t(nq, -1), best_d(nq, INT_MAX), second_d(nq, INT_MAX);
    std::vector<int> best_q_for_t(nt, -1), best_d_for_t(nt, INT_MAX);
    for (int i = 0; i < nq; ++i) {
      for (int j = 0; j < nt; ++j) {
        const int d = HammingDistance(query[i], train[j]);
        if (d < best_d[i]) {
          second_d[i] = best_d[i];
          best_d[i] = d;
          best_t[i] = j;
        } else if (d < second_d[i]) {
          second_d[i] = d;
        }
        if (d < best_d_for_t[j]) {
          best_d_for_t[j] = d;
          best_q_for_t[j] = i;
        }
      }
    }
    std::vector<DescriptorMatch> out;
    for (int i = 0; i < nq; ++i) {
      if (best_t[i] < 0 || best_d[i] > o.max_distance) continue;
      if (o.ratio < 1.0 && second_d[i] != INT_MAX && !(best_d[i] < o.ratio * second_d[i])) continue;
      if (o.mutual && best_q_for_t[best_t[i]] != i) continue;
      out.push_back({i, best_t[i], best_d[i]});
    }
    return out;
  };
  auto rng = test::SeededRng(5);
  const auto sparse = [&] {  // 12 random bits set: many equal distances
    Descriptor d{0, 0, 0, 0};
    for (int b = 0; b < 12; ++b) {
      const uint64_t bit = rng() % 256;
      d[bit / 64] |= 1ull << (bit % 64);
    }
    return d;
  };
  int compared = 0, nonempty = 0;
  for (const int nq : {1, 15, 16, 17, 40}) {
    for (const int nt : {1, 7, 300}) {
      std::vector<Descriptor> query(static_cast<size_t>(nq)), train(static_cast<size_t>(nt));
      for (auto& d : query) d = sparse();
      for (auto& d : train) d = sparse();
      for (const double ratio : {1.0, 0.9}) {
        for (const bool mutual : {false, true}) {
          MatchOptions o;
          o.ratio = ratio;
          o.mutual = mutual;
          o.max_distance = 20;
          const auto got = MatchDescriptors(query, train, o);
          const auto want = reference(query, train, o);
          ASSERT_EQ(got.size(), want.size()) << nq << "x" << nt;
          for (size_t k = 0; k < got.size(); ++k) {
            EXPECT_EQ(got[k].query, want[k].query);
            EXPECT_EQ(got[k].train, want[k].train) << nq << "x" << nt << " row " << k;
            EXPECT_EQ(got[k].distance, want[k].distance);
          }
          ++compared;
          nonempty += !want.empty();
        }
      }
    }
  }
  EXPECT_EQ(compared, 60);
  EXPECT_GE(nonempty, 30);  // the comparison is not of empty results
}

// RankByProbe against the brute-force ranking (every record scored in full, sorted): one stage
// gives exactly its first `keep`; the coarse stage keeps records whose best-ranked (first)
// descriptors the probe holds: three planted revisits among 2,000 random records come first either
// way, and with coarse_keep >= n the two stages are the one.
TEST(Matching, RankByProbeIsTheBruteForceRankingAndTheCoarseStageKeepsRevisits) {
  auto rng = test::SeededRng(21);
  std::vector<std::vector<Descriptor>> records(2000);
  for (auto& r : records) {
    r.resize(15);
    for (auto& d : r) d = Random(rng);
  }
  std::vector<Descriptor> probe;
  for (int j = 0; j < 15; ++j) probe.push_back(Random(rng));
  for (const size_t planted : {123u, 777u, 1999u}) {
    for (int j = 0; j < 6; ++j)
      records[planted][static_cast<size_t>(j)] =
          FlipBits(probe[static_cast<size_t>(2 * j)], 20, rng);
  }
  // Record 500 holds only probe descriptor 10 (beyond a 4-descriptor coarse probe).
  records[500][0] = FlipBits(probe[10], 20, rng);
  const auto stored = [&](size_t i) { return std::span<const Descriptor>(records[i]); };
  std::vector<std::pair<ProbeScore, size_t>> all;
  for (size_t i = 0; i < records.size(); ++i)
    all.push_back({ScoreAgainstProbe(records[i], probe, 64), i});
  std::stable_sort(all.begin(), all.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  ProbeRankOptions o;
  o.keep = 20;
  o.coarse_features = 0;
  const std::vector<size_t> one = RankByProbe(records.size(), stored, probe, o);
  ASSERT_EQ(one.size(), 20u);
  for (size_t k = 0; k < one.size(); ++k) EXPECT_EQ(one[k], all[k].second) << k;
  const auto first3 = [](std::vector<size_t> v) {
    v.resize(3);
    std::sort(v.begin(), v.end());
    return v;
  };
  EXPECT_EQ(first3(one), (std::vector<size_t>{123, 777, 1999}));
  o.coarse_features = 4;
  o.coarse_keep = 200;
  const std::vector<size_t> two = RankByProbe(records.size(), stored, probe, o);
  ASSERT_EQ(two.size(), 20u);
  EXPECT_EQ(first3(two), (std::vector<size_t>{123, 777, 1999}));
  EXPECT_EQ(two[3], 500u);
  // coarse_probe: the coarse stage compares with the probe's first 4 only. The planted revisits
  // hold probe 0 and 2 in their first 4 and stay first; record 500 (probe 10) no longer passes
  // the coarse stage (it ties with every random record there, and the lower indices win).
  o.coarse_probe = 4;
  const std::vector<size_t> capped = RankByProbe(records.size(), stored, probe, o);
  EXPECT_EQ(first3(capped), (std::vector<size_t>{123, 777, 1999}));
  EXPECT_EQ(std::find(capped.begin(), capped.end(), 500u), capped.end());
  o.coarse_probe = 0;
  o.coarse_keep = records.size();
  EXPECT_EQ(RankByProbe(records.size(), stored, probe, o), one);
  // fine_features: the last stage scores the first 8 of 15; the planted revisits hold the probe
  // in their first 6, so they still come first, and the ranking is the brute force one over
  // the first 8 descriptors.
  o.fine_features = 8;
  const std::vector<size_t> fine = RankByProbe(records.size(), stored, probe, o);
  EXPECT_EQ(first3(fine), (std::vector<size_t>{123, 777, 1999}));
  std::vector<std::pair<ProbeScore, size_t>> first8;
  for (size_t i = 0; i < records.size(); ++i)
    first8.push_back(
        {ScoreAgainstProbe(std::span<const Descriptor>(records[i]).first(8), probe, 64), i});
  std::stable_sort(first8.begin(), first8.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  for (size_t k = 0; k < fine.size(); ++k) EXPECT_EQ(fine[k], first8[k].second) << k;
  o.fine_features = 0;
  // n <= keep: every index, in order.
  o.keep = 5000;
  const std::vector<size_t> every = RankByProbe(records.size(), stored, probe, o);
  ASSERT_EQ(every.size(), records.size());
  EXPECT_EQ(every[1999], 1999u);
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

// The fallback's pre-ranking score, hand-worked: stored {s0, s1, s2}; the probe holds s0 with
// 10 bits flipped (and a far copy with 100), s1 with exactly 64 (the bound: found), nothing near
// s2. found = 2, closeness = (64 + 1 - 10) + (64 + 1 - 64) = 56; at max_distance 63 s1 drops out.
// Planted copies (twins) both count: there is no ratio test.
TEST(Matching, ScoreAgainstProbeCountsStoredDescriptorsWithANearProbe) {
  auto rng = test::SeededRng(9);
  const std::vector<Descriptor> stored = {Random(rng), Random(rng), Random(rng)};
  const auto flip = [](Descriptor d, int bits) {  // the first `bits` bits, each once
    for (int b = 0; b < bits; ++b) d[b / 64] ^= 1ull << (b % 64);
    return d;
  };
  std::vector<Descriptor> probe = {flip(stored[0], 10), flip(stored[0], 100), flip(stored[1], 64)};
  for (const Descriptor& p : probe) ASSERT_GT(HammingDistance(p, stored[2]), 64);
  const ProbeScore s = ScoreAgainstProbe(stored, probe, 64);
  EXPECT_EQ(s.found, 2);
  EXPECT_EQ(s.closeness, 55 + 1);
  const ProbeScore tighter = ScoreAgainstProbe(stored, probe, 63);
  EXPECT_EQ(tighter.found, 1);
  EXPECT_EQ(tighter.closeness, 54);
  EXPECT_LT(tighter, s);
  probe.push_back(stored[2]);
  EXPECT_EQ(ScoreAgainstProbe(stored, probe, 64).found, 3);
  EXPECT_EQ(ScoreAgainstProbe(stored, {}, 64), ProbeScore{});
  EXPECT_EQ(ScoreAgainstProbe({}, probe, 64), ProbeScore{});
}

// Asymmetric matching against a brute-force oracle: 15 stored descriptors, 600 query ones, some
// stored descriptors planted in the query once (noisy), some twice (a repeated structure: the
// ratio test on the stored side must reject those), the rest absent.
TEST(Matching, StoredIntoQueryIsTheStoredSidesRatioTestAndMutual) {
  auto rng = test::SeededRng(5);
  std::vector<Descriptor> stored(15), query(600);
  for (auto& d : stored) d = Random(rng);
  for (auto& d : query) d = Random(rng);
  for (int j = 0; j < 10; ++j) query[40 * j + 7] = FlipBits(stored[j], 12, rng);
  for (int j = 0; j < 3; ++j) query[40 * j + 8] = query[40 * j + 7];  // twins
  const MatchOptions o;                                               // ratio 0.9, mutual, 64 bits
  const auto m = MatchStoredIntoQuery(query, stored, o);
  // Oracle: stored j -> best query q (first lowest), second best d2; kept when d1 <= max,
  // d1 < ratio d2 and q's best stored (first lowest) is j.
  std::set<std::pair<int, int>> expected;
  for (int j = 0; j < 15; ++j) {
    int q = -1, d1 = 1000, d2 = 1000;
    for (int i = 0; i < 600; ++i) {
      const int d = HammingDistance(stored[j], query[i]);
      if (d < d1) {
        d2 = d1;
        d1 = d;
        q = i;
      } else if (d < d2) {
        d2 = d;
      }
    }
    int back = -1, bd = 1000;
    for (int k = 0; k < 15; ++k)
      if (HammingDistance(query[q], stored[k]) < bd)
        bd = HammingDistance(query[q], stored[k]), back = k;
    if (d1 <= o.max_distance && d1 < o.ratio * d2 && back == j) expected.insert({q, j});
  }
  std::set<std::pair<int, int>> got;
  for (size_t i = 0; i < m.size(); ++i) {
    got.insert({m[i].query, m[i].train});
    EXPECT_EQ(m[i].distance, HammingDistance(query[m[i].query], stored[m[i].train]));
    if (i > 0) {
      EXPECT_LT(m[i - 1].query, m[i].query);  // sorted by query index
    }
  }
  EXPECT_EQ(got, expected);
  // The 7 planted singles (3..9) are found; the twins' stored descriptors (0..2) are not.
  EXPECT_EQ(got.size(), 7u);
  for (const auto& [q, j] : got) EXPECT_EQ(q, 40 * j + 7);
  // The query-side ratio test (MatchDescriptors(query, stored)) does not see the twins.
  EXPECT_EQ(MatchDescriptors(query, stored, o).size(), 10u);
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

// Appends one correspondence (normalised observations of the two camera-frame points, plus
// `noise` on match x, y and query x, y) to the scene.
void AddCorrespondence(const Eigen::Vector3d& p_in_match, const Eigen::Vector3d& p_in_query,
                       const Eigen::Vector4d& noise, Scene* s) {
  CompactKeypoint km, kq;
  km.x = float(p_in_match.x() / p_in_match.z() + noise(0));
  km.y = float(p_in_match.y() / p_in_match.z() + noise(1));
  kq.x = float(p_in_query.x() / p_in_query.z() + noise(2));
  kq.y = float(p_in_query.y() / p_in_query.z() + noise(3));
  const int i = static_cast<int>(s->matches.size());
  s->match.keypoints.push_back(km);
  s->query.keypoints.push_back(kq);
  s->matches.push_back({i, i, 10});
  s->query.focal_px = s->match.focal_px = 500.0f;
  s->query.descriptors.resize(s->matches.size());
  s->match.descriptors.resize(s->matches.size());
}

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
    AddCorrespondence(p_in_match, p_in_query, Eigen::Vector4d::Zero(), &s);
    if (depths_match) s.match.depths.push_back(float(p_in_match.z()));
    if (depths_query) s.query.depths.push_back(float(p_in_query.z() / scale_query));
  }
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

// A scene on one plane (z = 5 + 0.4 x in the match camera) seen with a short baseline and a
// 12 deg rotation, observations with 0.5 px noise (f = 500 px): the two-view geometry of a
// planar scene, where the essential matrix is not unique.
Scene MakePlanarScene(uint64_t seed, int n) {
  auto rng = test::SeededRng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::normal_distribution<double> noise(0.0, 0.5 / 500.0);
  Scene s;
  s.match_from_query =
      Rigid3d(ExpSO3(Eigen::Vector3d(0.03, 0.2, 0.05)), Eigen::Vector3d(0.3, 0.05, 0.1));
  const Rigid3d query_from_match = s.match_from_query.Inverse();
  for (int i = 0; i < n; ++i) {
    const double x = 2.5 * u(rng), y = 1.5 * u(rng);
    const Eigen::Vector3d p_in_match(x, y, 5 + 0.4 * x);
    const Eigen::Vector3d p_in_query = query_from_match * p_in_match;
    Eigen::Vector4d e;
    for (int k = 0; k < 4; ++k) e(k) = noise(rng);  // in order (argument order is unspecified)
    AddCorrespondence(p_in_match, p_in_query, e, &s);
  }
  return s;
}

// On a plane the homography's decompositions give the true pose among the candidates (primary or
// an alternative), every alternative is a distinct, supported model, and the call is
// deterministic. Checked over several scenes: a single lucky draw would not show it.
TEST(Verification, PlanarAlternativesContainTheTruthOnAPlane) {
  int primary_wrong = 0;
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    SCOPED_TRACE(seed);
    const Scene s = MakePlanarScene(seed, 80);
    const VerifyOptions o;
    const VerificationResult v = VerifyPair(s.query, s.match, s.matches, o);
    ASSERT_TRUE(v.success);
    ASSERT_EQ(v.pose_kind, RelativePoseKind::kSE3UnitTranslation);
    const std::vector<VerificationResult> alts =
        PlanarAlternatives(s.query, s.match, s.matches, v, o);
    auto error_deg = [&](const VerificationResult& r) {
      return RotationAngle(r.match_from_query.rotation, s.match_from_query.rotation) * 180 / M_PI;
    };
    double best = error_deg(v);
    if (best > 1.0) ++primary_wrong;
    for (size_t k = 0; k < alts.size(); ++k) {
      const VerificationResult& a = alts[k];
      EXPECT_TRUE(a.success);
      EXPECT_EQ(a.method, VerificationMethod::kEssential);
      EXPECT_EQ(a.pose_kind, RelativePoseKind::kSE3UnitTranslation);
      EXPECT_GE(a.inliers, o.min_inliers);
      EXPECT_EQ(a.inliers, static_cast<int>(a.inlier_matches.size()));
      EXPECT_NEAR(a.match_from_query.translation.norm(), 1.0, 1e-9);
      EXPECT_GE(RotationAngle(a.match_from_query.rotation, v.match_from_query.rotation),
                0.5 * M_PI / 180);
      if (k > 0) {
        EXPECT_GE(alts[k - 1].inliers, a.inliers);  // most inliers first
        EXPECT_GE(RotationAngle(a.match_from_query.rotation, alts[0].match_from_query.rotation),
                  0.5 * M_PI / 180);
      }
      best = std::min(best, error_deg(a));
    }
    EXPECT_LT(best, 1.0);
    const std::vector<VerificationResult> again =
        PlanarAlternatives(s.query, s.match, s.matches, v, o);
    ASSERT_EQ(again.size(), alts.size());
    for (size_t k = 0; k < alts.size(); ++k)
      EXPECT_EQ(again[k].match_from_query.rotation.coeffs(),
                alts[k].match_from_query.rotation.coeffs());
  }
  // The case the alternatives exist for: the lowest-cost model is not always the true one.
  std::printf("planar scenes: primary > 1 deg off in %d of 8\n", primary_wrong);
  EXPECT_GE(primary_wrong, 1);
}

TEST(Verification, PlanarAlternativesOnlyForTwoViewPoses) {
  const Scene with_depths = MakeScene(23, 60, 0, false, true);
  const VerificationResult pnp =
      VerifyPair(with_depths.query, with_depths.match, with_depths.matches, VerifyOptions{});
  ASSERT_EQ(pnp.method, VerificationMethod::kPnP);
  EXPECT_TRUE(PlanarAlternatives(with_depths.query, with_depths.match, with_depths.matches, pnp,
                                 VerifyOptions{})
                  .empty());
  // Random correspondences support no homography with min_inliers.
  const Scene random = MakeScene(22, 60, 60, false, false);
  const VerificationResult v =
      VerifyPair(random.query, random.match, random.matches, VerifyOptions{});
  EXPECT_TRUE(
      PlanarAlternatives(random.query, random.match, random.matches, v, VerifyOptions{}).empty());
}

TEST(Verification, RandomCorrespondencesFail) {
  Scene s = MakeScene(22, 60, 60, false, false);  // all outliers
  const auto v = VerifyPair(s.query, s.match, s.matches, VerifyOptions{});
  EXPECT_FALSE(v.success);
  EXPECT_LT(v.inliers, VerifyOptions{}.min_inliers);
}

// RANSAC stops once a model with the fewest inliers that can pass would have been found
// (probability `confidence`): hand-worked counts.
TEST(Verification, IterationsToFindPassingModelHandWorked) {
  VerifyOptions o;  // confidence 0.999, max_iterations 1000
  o.min_inliers = 8;
  // n = 10, floor 8, 5-point: P(all-inlier sample) = 8*7*6*5*4 / (10*9*8*7*6) = 2/9;
  // log(0.001) / log(7/9) = 27.49 -> 28, raised to the minimum of 100.
  EXPECT_EQ(matching_internal::IterationsToFindPassingModel(o, 10, 5), 100);
  // n = 15: 6720 / 360360 -> 366.97 -> 367.
  EXPECT_EQ(matching_internal::IterationsToFindPassingModel(o, 15, 5), 367);
  // Every match must be an inlier: the minimum.
  EXPECT_EQ(matching_internal::IterationsToFindPassingModel(o, 8, 5), 100);
  // n = 12, floor 6 (weak pairs): 720 / 95040 -> 908.4 -> 909.
  o.min_inliers = 6;
  EXPECT_EQ(matching_internal::IterationsToFindPassingModel(o, 12, 5), 909);
  o.max_iterations = 50;  // a cap below the minimum wins
  EXPECT_EQ(matching_internal::IterationsToFindPassingModel(o, 8, 5), 50);
  o.max_iterations = 1000;
  o.min_inliers = 8;
  // Many matches, a low floor: the cap.
  EXPECT_EQ(matching_internal::IterationsToFindPassingModel(o, 1000, 5), 1000);
  // The ratio floor counts when it is higher: 0.8 * 15 = 12 with min_inliers 6:
  // 12*11*10*9*8 / 360360 = 0.2637 -> 23.7 -> 24, raised to 100; floor 6 alone would give 1000.
  o.min_inliers = 6;
  EXPECT_EQ(matching_internal::IterationsToFindPassingModel(o, 15, 5), 1000);
  o.min_inlier_ratio = 0.8;
  EXPECT_EQ(matching_internal::IterationsToFindPassingModel(o, 15, 5), 100);
}

// The shortened search finds what the full search finds: 15 matches, 8 of them true, over 100
// scenes. With min_inliers 8 RANSAC stops after 367 iterations; with min_inliers 5 it runs all
// 1000 (the search before the cap), and its results are then held to the floor of 8.
TEST(Verification, PairAtTheInlierFloorIsFoundAsOftenWithFewerIterations) {
  int capped = 0, full = 0;
  for (uint64_t seed = 0; seed < 100; ++seed) {
    const Scene s = MakeScene(1000 + seed, 15, 7, false, false);
    VerifyOptions o;
    o.seed = seed;
    o.min_inliers = 8;
    capped += VerifyPair(s.query, s.match, s.matches, o).success;
    o.min_inliers = 5;
    ASSERT_EQ(matching_internal::IterationsToFindPassingModel(o, 15, 5), o.max_iterations);
    full += VerifyPair(s.query, s.match, s.matches, o).inliers >= 8;
  }
  EXPECT_GE(full, 70);  // the scene is verifiable at all
  EXPECT_GE(capped, full - 2);
}

// The same for Sim(3) RANSAC (depths on both sides): with min_inliers 8 of 15 a 3-point sample
// is all inliers of a passing model with probability 8*7*6 / (15*14*13) = 0.123, so RANSAC stops
// after 53 -> 100 iterations instead of 1000 and finds the pair as often as the full search.
TEST(Verification, Sim3PairAtTheInlierFloorIsFoundAsOftenWithFewerIterations) {
  VerifyOptions hand;
  hand.min_inliers = 8;
  EXPECT_EQ(matching_internal::IterationsToFindPassingModel(hand, 15, 3), 100);
  // n = 30: 336 / 24360 = 0.0138 -> log(0.001) / log(1 - 0.0138) = 497.4 -> 498.
  EXPECT_EQ(matching_internal::IterationsToFindPassingModel(hand, 30, 3), 498);
  int capped = 0, full = 0;
  for (uint64_t seed = 0; seed < 100; ++seed) {
    const Scene s = MakeScene(3000 + seed, 15, 7, true, true);
    VerifyOptions o;
    o.seed = seed;
    o.min_inliers = 8;
    const VerificationResult c = VerifyPair(s.query, s.match, s.matches, o);
    capped += c.success && c.method == VerificationMethod::kSim3;
    o.min_inliers = 5;  // with this confidence: all 1000 iterations, the search before the cap
    o.confidence = 1 - 1e-12;
    ASSERT_EQ(matching_internal::IterationsToFindPassingModel(o, 15, 3), o.max_iterations);
    const VerificationResult f = VerifyPair(s.query, s.match, s.matches, o);
    full += f.method == VerificationMethod::kSim3 && f.inliers >= 8;
  }
  EXPECT_GE(full, 70);  // the scene is verifiable at all
  EXPECT_GE(capped, full - 2);
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
// scene with the query's depths intact takes the Sim(3) path (previous test). The scale from the
// query's depths (AddScaleFromQueryDepths) is then weak: its information says so.
TEST(Verification, BadDepthsOnOneSideFallBackToPnP) {
  Scene s = MakeScene(27, 60, 10, true, true);
  auto rng = test::SeededRng(28);
  std::uniform_real_distribution<double> log_factor(std::log(0.5), std::log(2.0));
  for (float& d : s.query.depths) d *= static_cast<float>(std::exp(log_factor(rng)));
  VerifyOptions scale_one;
  scale_one.scale_from_query_depths_min = 0;
  for (const VerifyOptions& o : {scale_one, VerifyOptions{}}) {
    const auto v = VerifyPair(s.query, s.match, s.matches, o);
    ASSERT_TRUE(v.success);
    EXPECT_EQ(v.method, VerificationMethod::kPnP);
    EXPECT_GE(v.inliers, 48);
    EXPECT_LT(RotationAngle(v.match_from_query.rotation, s.match_from_query.rotation), 1e-3);
    EXPECT_LT((v.match_from_query.translation - s.match_from_query.translation).norm(), 1e-2);
    if (o.scale_from_query_depths_min == 0) {
      EXPECT_EQ(v.pose_kind, RelativePoseKind::kSE3Metric);
      EXPECT_EQ(v.match_from_query.scale, 1.0);
      EXPECT_LT(v.information(6, 6), 1e-12 * v.information.trace());  // PnP: the scale is free
    } else {
      EXPECT_EQ(v.pose_kind, RelativePoseKind::kSim3);
      // True scale 1; factors spread over [0.5, 2]: a sigma of log s of 0.05-0.2, and the
      // estimate within 3 of them.
      const double sigma = 1 / std::sqrt(v.information(6, 6));
      EXPECT_GT(sigma, 0.05);
      EXPECT_LT(sigma, 0.2);
      EXPECT_LT(std::abs(std::log(v.match_from_query.scale)), 3 * sigma);
    }
  }
}

// Scale drift between the two places (query depths in units of 0.5 match units) and query depths
// with 30 % noise (a vSLAM's semi-dense depths far from its baseline): the 3-point Sim(3) RANSAC
// does not verify (the premise), PnP does, and the query's depths give the relative scale: the loop
// is a Sim(3) with scale 0.5, not a PnP pose at scale 1 (a 100 % error PCM would have to reject).
// Below scale_from_query_depths_min query depths the PnP pose is kept as it was.
TEST(Verification, PnPFallbackTakesTheScaleFromTheQueryDepths) {
  Scene s = MakeScene(29, 60, 10, true, true, 0.5);
  auto rng = test::SeededRng(30);
  std::normal_distribution<double> noise(0.0, 0.3);
  for (float& d : s.query.depths) d *= static_cast<float>(std::exp(noise(rng)));
  const auto v = VerifyPair(s.query, s.match, s.matches, VerifyOptions{});
  ASSERT_TRUE(v.success);
  ASSERT_EQ(v.method, VerificationMethod::kPnP);  // premise: no Sim(3) from these depths
  EXPECT_EQ(v.pose_kind, RelativePoseKind::kSim3);
  const double sigma = 1 / std::sqrt(v.information(6, 6));
  EXPECT_LT(sigma, 0.08);  // 50 inliers with 30 % noise: about 0.3 / sqrt(50) = 0.04
  EXPECT_LT(std::abs(std::log(v.match_from_query.scale / 0.5)), 3 * sigma);
  EXPECT_LT(RotationAngle(v.match_from_query.rotation, s.match_from_query.rotation), 1e-3);
  EXPECT_LT((v.match_from_query.translation - s.match_from_query.translation).norm(), 1e-2);
  // Rotation and translation information as PnP's: the same pose, rescaled columns aside.
  VerifyOptions scale_one;
  scale_one.scale_from_query_depths_min = 0;
  const auto pnp = VerifyPair(s.query, s.match, s.matches, scale_one);
  ASSERT_EQ(pnp.pose_kind, RelativePoseKind::kSE3Metric);
  EXPECT_EQ(pnp.inliers, v.inliers);
  const double rotation_info = pnp.information.block<3, 3>(3, 3).trace();
  const double rotation_info_scaled = v.information.block<3, 3>(3, 3).trace();
  EXPECT_NEAR(rotation_info_scaled, rotation_info, 1e-6 * rotation_info);
  // Only 4 query depths left among the matches: fewer than the default 5, scale 1 as before.
  Scene few = s;
  for (size_t i = 4; i < few.query.depths.size(); ++i) few.query.depths[i] = 0;
  const auto kept = VerifyPair(few.query, few.match, few.matches, VerifyOptions{});
  ASSERT_TRUE(kept.success);
  EXPECT_EQ(kept.pose_kind, RelativePoseKind::kSE3Metric);
  EXPECT_EQ(kept.match_from_query.scale, 1.0);
  VerifyOptions bad;
  bad.scale_from_query_depths_min = 2;  // a median of two is no estimate
  EXPECT_THROW(bad.Check(), std::invalid_argument);
}

}  // namespace
}  // namespace sparseloop
