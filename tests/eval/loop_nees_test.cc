#include "sparseloop/eval/loop_nees.h"

#include <cmath>
#include <random>
#include <stdexcept>

#include <gtest/gtest.h>
#include <Eigen/Cholesky>
#include <Eigen/Geometry>

namespace sparseloop {
namespace {

using Info7 = Eigen::Matrix<double, 7, 7>;

Rigid3d Pose(double yaw, const Eigen::Vector3d& t) {
  return Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY())), t);
}

// A point seen by the query, in the query's raw units (s_q per metre), lands where the match sees
// it in the match's raw units (s_m per metre) under the exact loop pose.
TEST(LoopNees, ExactLoopPoseMapsRawUnitsOfTheQueryToThoseOfTheMatch) {
  const Rigid3d world_from_match = Pose(0.3, {1.0, 0.2, -4.0});
  const Rigid3d world_from_query = Pose(-0.2, {3.0, 0.1, 2.0});
  const double s_m = 1.7, s_q = 0.8;
  const Sim3d exact = ExactLoopPose(world_from_match, world_from_query, s_m, s_q);
  const Eigen::Vector3d x_world(2.0, -1.0, 9.0);  // metres
  const Eigen::Vector3d in_query_raw = s_q * (world_from_query.Inverse() * x_world);
  const Eigen::Vector3d in_match_raw = s_m * (world_from_match.Inverse() * x_world);
  EXPECT_LT((exact * in_query_raw - in_match_raw).norm(), 1e-12);
  EXPECT_NEAR(exact.scale, s_m / s_q, 1e-15);
  EXPECT_THROW(ExactLoopPose(world_from_match, world_from_query, 0.0, 1.0), std::invalid_argument);
}

// e = log(measured^-1 exact): a known error gives e^T Omega e; a direction the information does
// not observe (a free scale) neither counts in the NEES nor as a degree of freedom.
TEST(LoopNees, ErrorInTheGraphTangentWeighedByTheInformation) {
  const Sim3d measured(1.1, Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX())),
                       Eigen::Vector3d(0.5, -2.0, 3.0));
  Vector7d e;
  e << 0.01, -0.02, 0.03, 0.002, -0.001, 0.003, 0.02;
  const Sim3d exact = measured * Sim3d::Exp(e);
  Info7 info = Info7::Zero();
  info.diagonal() << 100, 200, 300, 1e4, 2e4, 3e4, 500;
  const LoopNees full = ComputeLoopNees(measured, info, exact);
  EXPECT_EQ(full.dof, 7);
  EXPECT_NEAR(full.nees, e.dot(info * e), 1e-9);
  EXPECT_NEAR(ComputeLoopNees(measured, info, measured).nees, 0.0, 1e-20);
  info(6, 6) = 0.0;  // PnP against the match's points: the scale is free
  const LoopNees free_scale = ComputeLoopNees(measured, info, exact);
  EXPECT_EQ(free_scale.dof, 6);
  Vector7d e6 = e;
  e6(6) = 0.0;
  EXPECT_NEAR(free_scale.nees, e6.dot(info * e6), 1e-9);
  Info7 bad = info;
  bad(0, 1) = 5.0;  // not symmetric
  EXPECT_THROW(ComputeLoopNees(measured, bad, exact), std::invalid_argument);
  bad = info;
  bad(2, 2) = -100.0;  // not positive semidefinite
  EXPECT_THROW(ComputeLoopNees(measured, bad, exact), std::invalid_argument);
  bad = info;
  bad(3, 3) = std::nan("");
  EXPECT_THROW(ComputeLoopNees(measured, bad, exact), std::invalid_argument);
}

// Errors drawn from the covariance the information claims: the mean NEES per dof falls inside
// the 95 % band, about 5 % of loops above the 95 % quantile; claiming 4x the information puts the
// mean at ~4, outside the band.
TEST(LoopNees, ErrorsDrawnFromTheClaimedCovarianceAreInsideTheBand) {
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  Info7 a = Info7::Random();
  const Info7 cov = 1e-4 * (a * a.transpose() + Info7::Identity());
  const Info7 info = cov.inverse();
  const Info7 chol = cov.llt().matrixL();
  const Sim3d measured(0.9, Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 2, 3));
  std::vector<LoopNees> honest, overconfident;
  for (int i = 0; i < 400; ++i) {
    Vector7d z;
    for (int k = 0; k < 7; ++k) z(k) = normal(rng);
    const Sim3d exact = measured * Sim3d::Exp(chol * z);
    honest.push_back(ComputeLoopNees(measured, info, exact));
    overconfident.push_back(ComputeLoopNees(measured, 4.0 * info, exact));
  }
  const LoopNeesSummary h = SummarizeLoopNees(honest);
  EXPECT_EQ(h.loops, 400);
  EXPECT_GE(h.mean_ratio, h.band_low);
  EXPECT_LE(h.mean_ratio, h.band_high);
  EXPECT_GT(h.above_95, 5);
  EXPECT_LT(h.above_95, 40);
  EXPECT_LE(h.beyond_3_sigma, 5);
  const LoopNeesSummary o = SummarizeLoopNees(overconfident);
  EXPECT_GT(o.mean_ratio, o.band_high);
  EXPECT_NEAR(o.mean_ratio, 4.0 * h.mean_ratio, 1e-9);
  EXPECT_GT(o.beyond_3_sigma, 40);
  EXPECT_EQ(SummarizeLoopNees({}).loops, 0);
}

}  // namespace
}  // namespace sparseloop
