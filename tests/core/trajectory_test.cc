#include "sparseloop/core/trajectory.h"

#include <random>

#include <gtest/gtest.h>

namespace sparseloop {
namespace {

// NearestInTime against a brute-force scan: nearest stamp, the earlier on a tie, none beyond
// max_dt; over random sorted stamps with repeated gaps (ties) and queries on and between stamps.
TEST(Trajectory, NearestInTimeEqualsBruteForce) {
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

// One cumulative path length for any range of points (3D trajectories, 2D plans): the running
// sum of the step lengths, 0 for the first (and for an empty range, nothing).
TEST(Trajectory, CumulativePathLengthSumsTheSteps) {
  const std::vector<Eigen::Vector2d> plan = {{0, 0}, {3, 4}, {3, 4}, {0, 0}};
  const auto identity = [](const Eigen::Vector2d& p) { return p; };
  EXPECT_EQ(CumulativePathLength(plan, identity), (std::vector<double>{0.0, 5.0, 5.0, 10.0}));
  EXPECT_TRUE(CumulativePathLength(std::vector<Eigen::Vector2d>{}, identity).empty());
  Trajectory t;
  for (int i = 0; i < 4; ++i)
    t.poses.push_back({double(i), i, Rigid3d(Eigen::Quaterniond::Identity(), {0, 0, 2.0 * i})});
  EXPECT_EQ(t.CumulativeDistances(), (std::vector<double>{0.0, 2.0, 4.0, 6.0}));
}

}  // namespace
}  // namespace sparseloop
