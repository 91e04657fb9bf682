#include "sparseloop/core/time_association.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <tuple>

#include <gtest/gtest.h>

#include "sparseloop/core/trajectory.h"

namespace sparseloop {
namespace {

using Partners = std::vector<std::optional<size_t>>;

// The documented rule by brute force: every pair with |dt| <= max_dt, in the order (|dt|, query,
// reference stamp, reference index); kNearest gives each query its first pair, kOneToOne takes
// the pairs greedily with every reference at most once.
Partners BruteForce(const std::vector<double>& queries, const std::vector<double>& references,
                    double max_dt, TimePairing pairing) {
  std::vector<std::tuple<double, size_t, double, size_t>> candidates;
  for (size_t i = 0; i < queries.size(); ++i) {
    for (size_t j = 0; j < references.size(); ++j) {
      const double dt = std::abs(references[j] - queries[i]);
      if (dt <= max_dt) candidates.emplace_back(dt, i, references[j], j);
    }
  }
  std::sort(candidates.begin(), candidates.end());
  Partners out(queries.size());
  std::vector<bool> used(references.size(), false);
  for (const auto& [dt, i, stamp, j] : candidates) {
    if (out[i] || (pairing == TimePairing::kOneToOne && used[j])) continue;
    out[i] = j;
    used[j] = true;
  }
  return out;
}

// Stamps on a 0.25 s grid (midpoints are exact ties), with repeats (step 0), gaps beyond every
// max_dt tried but the last (step 3) and any order.
std::vector<double> RandomStamps(std::mt19937_64& rng, int max_count, bool shuffle) {
  std::uniform_int_distribution<int> count(0, max_count), step(0, 5);
  const double steps[] = {0.0, 0.25, 0.5, 0.75, 1.0, 3.0};
  std::vector<double> stamps;
  double t = -1.0;
  for (int n = count(rng); n > 0; --n) stamps.push_back(t += steps[step(rng)]);
  if (shuffle) std::shuffle(stamps.begin(), stamps.end(), rng);
  return stamps;
}

TEST(TimeAssociation, BothPairingsEqualBruteForceOnRandomStamps) {
  std::mt19937_64 rng(44);
  for (int trial = 0; trial < 2000; ++trial) {
    const bool shuffle = trial % 2 == 1;
    const std::vector<double> queries = RandomStamps(rng, 14, shuffle);
    const std::vector<double> references = RandomStamps(rng, 14, shuffle);
    for (const double max_dt : {0.0, 0.25, 0.5, 1.0, 10.0}) {
      for (const TimePairing pairing : {TimePairing::kNearest, TimePairing::kOneToOne}) {
        ASSERT_EQ(AssociateInTime(queries, references, max_dt, pairing),
                  BruteForce(queries, references, max_dt, pairing))
            << "trial " << trial << " max_dt " << max_dt << " one-to-one "
            << (pairing == TimePairing::kOneToOne);
      }
    }
  }
}

// NearestInTime is kNearest for one query: over a sorted range and over a std::map searched with
// its own lower_bound, for queries on, between and far from the stamps.
TEST(TimeAssociation, NearestInTimeIsTheNearestPairingForOneQuery) {
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 300; ++trial) {
    const std::vector<double> references = RandomStamps(rng, 12, false);
    std::map<double, size_t> first_of_stamp;
    for (size_t j = 0; j < references.size(); ++j) first_of_stamp.emplace(references[j], j);
    for (double q = -2.0; q <= 40.0; q += 0.125) {
      for (const double max_dt : {0.0, 0.25, 0.6, 10.0}) {
        const std::optional<size_t> expected =
            AssociateInTime({q}, references, max_dt, TimePairing::kNearest)[0];
        const auto stamp = [](double s) { return s; };
        EXPECT_EQ(NearestInTime(references, q, max_dt, stamp), expected) << q << " " << max_dt;
        const auto it =
            NearestInTime(first_of_stamp.begin(), first_of_stamp.lower_bound(q),
                          first_of_stamp.end(), q, max_dt, [](const auto& e) { return e.first; });
        EXPECT_EQ(it == first_of_stamp.end() ? std::nullopt : std::optional(it->second), expected)
            << q << " " << max_dt;
      }
    }
  }
}

// Known answers. A tie between the two sides goes to the earlier stamp, and among equal stamps to
// the first; kNearest lets two queries share a reference, kOneToOne gives the second its next.
TEST(TimeAssociation, KnownAnswers) {
  EXPECT_EQ(AssociateInTime({1.5}, {1.0, 1.0, 2.0}, 1.0, TimePairing::kNearest), (Partners{0}));
  EXPECT_EQ(AssociateInTime({0.5}, {1.0, 0.0}, 1.0, TimePairing::kNearest), (Partners{1}));
  EXPECT_EQ(AssociateInTime({0.0, 5.0}, {0.3}, 0.2, TimePairing::kNearest),
            (Partners{std::nullopt, std::nullopt}));
  const std::vector<double> est = {0.1, 0.104}, gt = {0.1, 0.13};
  EXPECT_EQ(AssociateInTime(est, gt, 0.03, TimePairing::kNearest), (Partners{0, 0}));
  EXPECT_EQ(AssociateInTime(est, gt, 0.03, TimePairing::kOneToOne), (Partners{0, 1}));
  EXPECT_EQ(AssociateInTime(est, gt, 0.01, TimePairing::kOneToOne), (Partners{0, std::nullopt}));
  // The greedy takes the smallest |dt| first, whichever query comes first.
  EXPECT_EQ(AssociateInTime({0.9, 1.05}, {1.0}, 0.2, TimePairing::kOneToOne),
            (Partners{std::nullopt, 0}));
  EXPECT_TRUE(AssociateInTime({}, {1.0}, 0.1, TimePairing::kOneToOne).empty());
  EXPECT_EQ(AssociateInTime({1.0}, {}, 0.1, TimePairing::kOneToOne), (Partners{std::nullopt}));
  EXPECT_THROW(AssociateInTime({1.0}, {1.0}, -0.1, TimePairing::kNearest), std::invalid_argument);
  EXPECT_THROW(AssociateInTime({1.0}, {1.0}, std::nan(""), TimePairing::kNearest),
               std::invalid_argument);
}

// The two pairings agree when no two queries are within 2 max_dt of each other (e.g. max_dt below
// half the smaller sampling period): no reference can then be a candidate of two queries.
TEST(TimeAssociation, PairingsAgreeWhenNoTwoQueriesAreWithinTwiceMaxDt) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> spacing(1.0, 2.0);
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<double> queries;
    double t = -2.0;
    for (int k = 0; k < 15; ++k) queries.push_back(t += spacing(rng));
    std::shuffle(queries.begin(), queries.end(), rng);
    const std::vector<double> references = RandomStamps(rng, 40, true);
    for (const double max_dt : {0.25, 0.49}) {
      EXPECT_EQ(AssociateInTime(queries, references, max_dt, TimePairing::kOneToOne),
                AssociateInTime(queries, references, max_dt, TimePairing::kNearest));
    }
  }
}

// NearestPoseInTime over a trajectory against a brute-force scan: nearest stamp, the earlier on a
// tie, none beyond max_dt; over random sorted stamps with repeated gaps (ties) and queries on and
// between stamps.
TEST(TimeAssociation, NearestPoseInTimeEqualsBruteForce) {
  std::mt19937_64 rng(7);
  std::uniform_int_distribution<int> gap(1, 4), n_dist(0, 12);
  for (int trial = 0; trial < 300; ++trial) {
    Trajectory traj;
    double t = 0.0;
    const int n = n_dist(rng);
    for (int i = 0; i < n; ++i) {
      t += 0.5 * gap(rng);  // multiples of 0.5: midpoints are exact ties
      traj.poses.push_back({t, i, Rigid3d()});
    }
    for (double q = -1.0; q <= t + 1.0; q += 0.25) {
      for (const double max_dt : {0.0, 0.25, 0.6, 10.0}) {
        std::optional<size_t> expected;
        for (size_t i = 0; i < traj.poses.size(); ++i) {
          const double d = std::abs(traj.poses[i].timestamp - q);
          if (d <= max_dt && (!expected || d < std::abs(traj.poses[*expected].timestamp - q))) {
            expected = i;
          }
        }
        EXPECT_EQ(NearestPoseInTime(traj, q, max_dt), expected)
            << "trial " << trial << " t=" << q << " max_dt=" << max_dt;
      }
    }
  }
}

}  // namespace
}  // namespace sparseloop
