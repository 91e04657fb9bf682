#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "sparseloop/core/quaternion.h"
#include "sparseloop/core/rigid3.h"
#include "sparseloop/core/sim3.h"
#include "test_util.h"

namespace sparseloop {
namespace {

Rigid3d RandomRigid(std::mt19937_64& rng, double rot_scale = 2.0) {
  std::normal_distribution<double> n(0.0, 1.0);
  Vector6d t;
  for (int i = 0; i < 6; ++i) t[i] = n(rng) * (i < 3 ? 3.0 : rot_scale / 2.0);
  return Rigid3d::Exp(t);
}

Sim3d RandomSim(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Vector7d t;
  for (int i = 0; i < 7; ++i) t[i] = n(rng) * (i < 3 ? 3.0 : (i < 6 ? 1.0 : 0.5));
  return Sim3d::Exp(t);
}

double Distance(const Sim3d& a, const Sim3d& b) { return (a.Inverse() * b).Log().norm(); }
double Distance(const Rigid3d& a, const Rigid3d& b) { return (a.Inverse() * b).Log().norm(); }

TEST(SO3, ExpOfKnownRotation) {
  const Eigen::Quaterniond q = ExpSO3(Eigen::Vector3d(0, 0, std::numbers::pi / 2));
  const Eigen::Vector3d x = q * Eigen::Vector3d::UnitX();
  EXPECT_NEAR((x - Eigen::Vector3d::UnitY()).norm(), 0.0, 1e-12);
}

TEST(SO3, LogNearPiAndZero) {
  for (double angle : {0.0, 1e-12, 1e-6, 0.5, 3.0, std::numbers::pi - 1e-9}) {
    const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, -0.5).normalized();
    const Eigen::Vector3d omega = axis * angle;
    EXPECT_NEAR((LogSO3(ExpSO3(omega)) - omega).norm(), 0.0, 1e-9) << angle;
  }
}

TEST(SO3, HatIsCrossProduct) {
  const Eigen::Vector3d a(1, -2, 3), b(0.5, 4, -1);
  EXPECT_NEAR((Hat(a) * b - a.cross(b)).norm(), 0.0, 1e-12);
}

TEST(Rigid3, ExpLogRoundTrip) {
  auto rng = test::SeededRng();
  for (int i = 0; i < 200; ++i) {
    const Rigid3d g = RandomRigid(rng);
    EXPECT_LT(Distance(Rigid3d::Exp(g.Log()), g), 1e-9);
  }
}

TEST(Rigid3, ComposeInverseAssociativity) {
  auto rng = test::SeededRng(1);
  for (int i = 0; i < 100; ++i) {
    const Rigid3d a = RandomRigid(rng), b = RandomRigid(rng), c = RandomRigid(rng);
    EXPECT_LT(Distance((a * b) * c, a * (b * c)), 1e-9);
    EXPECT_LT((a * a.Inverse()).Log().norm(), 1e-9);
    const Eigen::Vector3d p(1.5, -2.0, 0.25);
    EXPECT_NEAR(((a * b) * p - a * (b * p)).norm(), 0.0, 1e-9);
    EXPECT_NEAR((a.ToMatrix4() * p.homogeneous()).head<3>().isApprox(a * p, 1e-12), 1, 0);
  }
}

TEST(Rigid3, MatrixAndVectorRoundTrip) {
  auto rng = test::SeededRng(2);
  for (int i = 0; i < 50; ++i) {
    const Rigid3d a = RandomRigid(rng);
    EXPECT_LT(Distance(Rigid3d::FromMatrix3x4(a.ToMatrix3x4()), a), 1e-9);
    EXPECT_LT(Distance(Rigid3d::FromVector(a.ToVector()), a), 1e-12);
  }
}

TEST(Rigid3, FromMatrixRejectsNonRotation) {
  Matrix3x4d m = Matrix3x4d::Zero();
  m.leftCols<3>() = 1.5 * Eigen::Matrix3d::Identity();
  EXPECT_THROW(Rigid3d::FromMatrix3x4(m), std::invalid_argument);
  m.leftCols<3>() = -Eigen::Matrix3d::Identity();
  EXPECT_THROW(Rigid3d::FromMatrix3x4(m), std::invalid_argument);
  m.leftCols<3>() = Eigen::Matrix3d::Identity();
  m(0, 3) = std::nan("");
  EXPECT_THROW(Rigid3d::FromMatrix3x4(m), std::invalid_argument);
}

TEST(Sim3, ExpLogRoundTrip) {
  auto rng = test::SeededRng(3);
  for (int i = 0; i < 200; ++i) {
    const Sim3d g = RandomSim(rng);
    EXPECT_LT(Distance(Sim3d::Exp(g.Log()), g), 1e-8);
    // And log(exp(x)) == x for tangents with rotation angle < pi.
    const Vector7d x = g.Log();
    EXPECT_LT((Sim3d::Exp(x).Log() - x).norm(), 1e-8);
  }
}

TEST(Sim3, SmallAngleAndScaleBranches) {
  // Exercise the Taylor branches of W: each result must match a nearby generic evaluation.
  for (double s : {0.0, 1e-9, 0.3}) {
    for (double th : {0.0, 1e-9, 0.4}) {
      Vector7d x;
      x << 0.3, -0.1, 0.2, th, 0.0, 0.0, s;
      Vector7d y = x;
      y[3] += 1e-4;
      y[6] += 1e-4;
      EXPECT_LT((Sim3d::Exp(x).ToMatrix4() - Sim3d::Exp(y).ToMatrix4()).norm(), 1e-3);
      EXPECT_LT((Sim3d::Exp(x).Log() - x).norm(), 1e-9);
    }
  }
}

TEST(Sim3, ComposeInverseAssociativityAction) {
  auto rng = test::SeededRng(4);
  for (int i = 0; i < 100; ++i) {
    const Sim3d a = RandomSim(rng), b = RandomSim(rng), c = RandomSim(rng);
    EXPECT_LT(Distance((a * b) * c, a * (b * c)), 1e-8);
    EXPECT_LT((a * a.Inverse()).Log().norm(), 1e-9);
    const Eigen::Vector3d p(0.5, 2.0, -1.0);
    EXPECT_NEAR(((a * b) * p - a * (b * p)).norm(), 0.0, 1e-8);
    EXPECT_NEAR((a.Inverse() * (a * p) - p).norm(), 0.0, 1e-9);
    EXPECT_NEAR(((a.ToMatrix4() * p.homogeneous()).head<3>() - a * p).norm(), 0.0, 1e-9);
  }
}

TEST(Sim3, MatrixRoundTripAndScale) {
  auto rng = test::SeededRng(5);
  for (int i = 0; i < 50; ++i) {
    const Sim3d a = RandomSim(rng);
    const Sim3d b = Sim3d::FromMatrix3x4(a.ToMatrix3x4());
    EXPECT_NEAR(b.scale, a.scale, 1e-12 * a.scale);
    EXPECT_LT(Distance(a, b), 1e-9);
    EXPECT_LT(Distance(Sim3d::FromVector(a.ToVector()), a), 1e-12);
  }
  EXPECT_THROW(Sim3d(0.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero()),
               std::invalid_argument);
}

TEST(Sim3, RigidEmbedding) {
  auto rng = test::SeededRng(6);
  const Rigid3d a = RandomRigid(rng), b = RandomRigid(rng);
  const Sim3d ab = Sim3d(a) * Sim3d(b);
  EXPECT_LT(Distance(ab.ToRigid(), a * b), 1e-9);
  EXPECT_DOUBLE_EQ(ab.scale, 1.0);
}

TEST(Quaternion, OrderConversionsAreConsistent) {
  const Eigen::Quaterniond q = ExpSO3(Eigen::Vector3d(0.1, 0.2, 0.3));
  const auto xyzw = QuaternionToXyzw(q);
  const auto wxyz = QuaternionToWxyz(q);
  EXPECT_EQ(xyzw[3], wxyz[0]);
  EXPECT_EQ(xyzw[0], wxyz[1]);
  EXPECT_TRUE(QuaternionFromXyzw(xyzw[0], xyzw[1], xyzw[2], xyzw[3]).isApprox(q));
  EXPECT_TRUE(QuaternionFromWxyz(wxyz[0], wxyz[1], wxyz[2], wxyz[3]).isApprox(q));
  EXPECT_DOUBLE_EQ(q.w(), xyzw[3]);
}

}  // namespace
}  // namespace sparseloop
