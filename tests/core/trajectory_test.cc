#include "sparseloop/core/trajectory.h"

#include <gtest/gtest.h>

namespace sparseloop {
namespace {

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
