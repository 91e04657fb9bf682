// The templated Sim(3) math (sim3_jet.h) against core's double implementation, the vertex
// manifolds against Ceres' manifold invariants, and the edge residual's autodiff Jacobian against
// central finite differences.
#include <ceres/jet.h>
#include <ceres/manifold_test_utils.h>
#include <gmock/gmock.h>

#include "posegraph/edge_error.h"
#include "posegraph/manifolds.h"
#include "posegraph/sim3_jet.h"
#include "sparseloop/core/sim3.h"
#include "test_util.h"

namespace sparseloop {
namespace {

Vector7d RandomTangent(std::mt19937_64& rng, double t_scale, double r_scale, double s_scale) {
  std::normal_distribution<double> n(0.0, 1.0);
  Vector7d v;
  for (int i = 0; i < 3; ++i) v[i] = t_scale * n(rng);
  for (int i = 3; i < 6; ++i) v[i] = r_scale * n(rng);
  v[6] = s_scale * n(rng);
  return v;
}

TEST(Sim3Jet, ExpLogMatchCoreAcrossRegimes) {
  auto rng = test::SeededRng(1);
  // (translation, rotation, log-scale) magnitudes: generic, tiny rotation, tiny scale, both tiny,
  // exactly zero rotation / scale.
  const double regimes[][3] = {{1.0, 0.8, 0.3},   {1.0, 1e-6, 0.3},  {1.0, 0.8, 1e-6},
                               {1.0, 1e-7, 1e-7}, {1.0, 0.0, 0.5},   {1.0, 0.5, 0.0},
                               {1.0, 0.0, 0.0},   {1.0, 2e-5, 2e-3}, {1.0, 3e-3, 5e-5}};
  for (const auto& r : regimes) {
    for (int k = 0; k < 20; ++k) {
      const Vector7d tangent = RandomTangent(rng, r[0], r[1], r[2]);
      const Sim3d expected = Sim3d::Exp(tangent);
      const jet::Vector7<double> tj = tangent;
      const jet::Sim3<double> got = jet::Sim3<double>::Exp(tj);
      // core's Sim3LeftJacobianW switches to the sigma = 0 formulas for |sigma| < 1e-6 and so
      // is only accurate to O(|sigma| |upsilon|) there (the template keeps the first-order
      // terms): allow that much when comparing with core.
      const double core_tol = 1e-9 + (std::abs(tangent[6]) < 1e-6
                                          ? 2.0 * std::abs(tangent[6]) * tangent.head<3>().norm()
                                          : 0.0);
      EXPECT_NEAR(got.scale, expected.scale, 1e-12);
      EXPECT_LT((got.translation - expected.translation).norm(), core_tol)
          << "regime " << r[1] << " " << r[2];
      EXPECT_LT(got.rotation.angularDistance(expected.rotation), 1e-12);
      const Vector7d log_core = expected.Log();
      const Vector7d log_jet = ToJetSim3(expected).Log();
      EXPECT_LT((log_core - log_jet).norm(), 1e-8 + 2 * core_tol)
          << "regime " << r[1] << " " << r[2];
      // The template alone round-trips to high accuracy in every regime.
      EXPECT_LT((got.Log() - tangent).norm(), 1e-9) << "regime " << r[1] << " " << r[2];
    }
  }
}

TEST(Sim3Jet, ComposeAndInverseMatchCore) {
  auto rng = test::SeededRng(2);
  for (int k = 0; k < 20; ++k) {
    const Sim3d a = Sim3d::Exp(RandomTangent(rng, 2.0, 1.0, 0.5));
    const Sim3d b = Sim3d::Exp(RandomTangent(rng, 2.0, 1.0, 0.5));
    const jet::Sim3<double> c = ToJetSim3(a) * ToJetSim3(b).Inverse();
    const Sim3d expected = a * b.Inverse();
    EXPECT_NEAR(c.scale, expected.scale, 1e-12);
    EXPECT_LT((c.translation - expected.translation).norm(), 1e-10);
    EXPECT_LT(c.rotation.angularDistance(expected.rotation), 1e-12);
  }
}

// Derivative of log(exp(x)) must be the identity, also at x = 0 where the Taylor branches are
// used: that is exactly where residual Jacobians are evaluated at convergence.
TEST(Sim3Jet, JetDerivativeOfLogExpIsIdentity) {
  using J = ceres::Jet<double, 7>;
  auto rng = test::SeededRng(3);
  for (int k = 0; k < 12; ++k) {
    const Vector7d x = k == 0 ? Vector7d::Zero().eval() : RandomTangent(rng, 0.3, 0.3, 0.1);
    jet::Vector7<J> xj;
    for (int i = 0; i < 7; ++i) xj[i] = J(x[i], i);
    const jet::Vector7<J> y = jet::Sim3<J>::Exp(xj).Log();
    for (int i = 0; i < 7; ++i) {
      EXPECT_NEAR(y[i].a, x[i], 1e-9);
      for (int j = 0; j < 7; ++j) EXPECT_NEAR(y[i].v[j], i == j ? 1.0 : 0.0, 1e-7) << i << j;
    }
  }
}

Vector8d RandomPoint(std::mt19937_64& rng, VertexType type) {
  Vector7d t = RandomTangent(rng, 2.0, 1.0, type == VertexType::kSim3 ? 0.4 : 0.0);
  Sim3d s = Sim3d::Exp(t);
  if (type == VertexType::kSe2) {
    s = Sim3d(1.0, Eigen::Quaterniond(Eigen::AngleAxisd(t[5], Eigen::Vector3d::UnitZ())),
              Eigen::Vector3d(t[0], t[1], 0.0));
  }
  return s.ToVector();
}

template <typename M>
void CheckManifold(VertexType type, int tangent, double delta_scale) {
  M manifold;
  auto rng = test::SeededRng(4);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int k = 0; k < 10; ++k) {
    const Vector8d xv = RandomPoint(rng, type);
    const Vector8d yv = RandomPoint(rng, type);
    const Eigen::VectorXd x = xv;
    Eigen::VectorXd delta(tangent);
    for (int i = 0; i < tangent; ++i) delta[i] = delta_scale * n(rng);
    // y must lie on the manifold reachable from x: build it as Plus(x, d).
    Eigen::VectorXd d2(tangent);
    for (int i = 0; i < tangent; ++i) d2[i] = 0.5 * n(rng);
    Eigen::VectorXd y(8);
    manifold.Plus(x.data(), d2.data(), y.data());
    (void)yv;
    constexpr double kTolerance = 1e-8;
    using namespace ceres;  // the macro names ceres helpers unqualified
    EXPECT_THAT_MANIFOLD_INVARIANTS_HOLD(manifold, x, delta, y, kTolerance);
  }
}

TEST(Manifolds, Sim3InvariantsHold) { CheckManifold<Sim3Manifold>(VertexType::kSim3, 7, 0.5); }
TEST(Manifolds, Se3InvariantsHold) { CheckManifold<Se3OnSim3Manifold>(VertexType::kSe3, 6, 0.5); }
TEST(Manifolds, FourDofInvariantsHold) {
  CheckManifold<FourDofManifold>(VertexType::kFourDof, 4, 0.5);
}
TEST(Manifolds, Se2InvariantsHold) { CheckManifold<Se2OnSim3Manifold>(VertexType::kSe2, 3, 0.5); }

// The closed-form PlusJacobian equals the autodiff one of the same Plus, at random points
// (including a negative-w quaternion and non-unit scale).
template <typename Analytic, typename AutoDiff>
void CheckPlusJacobianMatchesAutodiff(VertexType type, int tangent) {
  const Analytic analytic;
  const AutoDiff autodiff;
  auto rng = test::SeededRng(11);
  for (int k = 0; k < 20; ++k) {
    Vector8d x = RandomPoint(rng, type);
    if (k % 2 == 1) x.head<4>() = -x.head<4>();  // the same rotation, other hemisphere
    if (type == VertexType::kSe3) x[7] = 1.3;    // a stored scale other than 1 multiplies R
    Eigen::Matrix<double, 8, Eigen::Dynamic, Eigen::RowMajor> ja(8, tangent), jd(8, tangent);
    ja.setConstant(7.0);  // every entry must be written
    ASSERT_TRUE(analytic.PlusJacobian(x.data(), ja.data()));
    ASSERT_TRUE(autodiff.PlusJacobian(x.data(), jd.data()));
    EXPECT_LT((ja - jd).cwiseAbs().maxCoeff(), 1e-12) << "point " << k << "\n"
                                                      << ja << "\n\n"
                                                      << jd;
  }
}

TEST(Manifolds, ClosedFormPlusJacobiansMatchAutodiff) {
  CheckPlusJacobianMatchesAutodiff<Sim3Manifold, Sim3AutoDiffManifold>(VertexType::kSim3, 7);
  CheckPlusJacobianMatchesAutodiff<Se3OnSim3Manifold, Se3OnSim3AutoDiffManifold>(VertexType::kSe3,
                                                                                 6);
  CheckPlusJacobianMatchesAutodiff<FourDofManifold, FourDofAutoDiffManifold>(VertexType::kFourDof,
                                                                             4);
  CheckPlusJacobianMatchesAutodiff<Se2OnSim3Manifold, Se2OnSim3AutoDiffManifold>(VertexType::kSe2,
                                                                                 3);
}

TEST(Manifolds, PlusIsRightMultiplicationByExp) {
  Sim3Manifold manifold;
  auto rng = test::SeededRng(5);
  const Sim3d x = Sim3d::Exp(RandomTangent(rng, 1.0, 1.0, 0.3));
  const Vector7d d = RandomTangent(rng, 0.3, 0.3, 0.1);
  const Vector8d xv = x.ToVector();
  Vector8d out;
  manifold.Plus(xv.data(), d.data(), out.data());
  const Sim3d expected = x * Sim3d::Exp(d);
  EXPECT_LT((Sim3d::FromVector(out).ToMatrix4() - expected.ToMatrix4()).norm(), 1e-12);
}

TEST(EdgeError, ZeroAtMeasurementAndJacobianMatchesFiniteDifferences) {
  auto rng = test::SeededRng(6);
  const Sim3d a = Sim3d::Exp(RandomTangent(rng, 2.0, 1.0, 0.3));
  const Sim3d b = Sim3d::Exp(RandomTangent(rng, 2.0, 1.0, 0.3));
  Matrix7d info = Matrix7d::Identity();
  info(0, 1) = info(1, 0) = 0.3;
  info(6, 6) = 4.0;
  const Matrix7d sqrt_info = SqrtInformation(info);
  EXPECT_LT((sqrt_info.transpose() * sqrt_info - info).norm(), 1e-12);
  // Zero residual when the measurement equals the estimate.
  {
    std::unique_ptr<ceres::CostFunction> cost(EdgeError::Create(a.Inverse() * b, sqrt_info));
    Vector8d av = a.ToVector(), bv = b.ToVector();
    const double* params[2] = {av.data(), bv.data()};
    Vector7d r;
    ASSERT_TRUE(cost->Evaluate(params, r.data(), nullptr));
    EXPECT_LT(r.norm(), 1e-9);
  }
  // Jacobian w.r.t. the manifold tangent (J * PlusJacobian) against finite differences of
  // r(Plus(x, d)) at d = 0, with a measurement that does not agree with the estimate.
  const Sim3d z = Sim3d::Exp(RandomTangent(rng, 0.2, 0.2, 0.1)) * a.Inverse() * b;
  std::unique_ptr<ceres::CostFunction> cost(EdgeError::Create(z, sqrt_info));
  Sim3Manifold manifold;
  Vector8d av = a.ToVector(), bv = b.ToVector();
  Eigen::Matrix<double, 7, 8, Eigen::RowMajor> ja, jb;
  double* jacobians[2] = {ja.data(), jb.data()};
  const double* params[2] = {av.data(), bv.data()};
  Vector7d r0;
  ASSERT_TRUE(cost->Evaluate(params, r0.data(), jacobians));
  for (int block = 0; block < 2; ++block) {
    Vector8d& x = block == 0 ? av : bv;
    Eigen::Matrix<double, 8, 7, Eigen::RowMajor> plus_jac;
    manifold.PlusJacobian(x.data(), plus_jac.data());
    const Eigen::Matrix<double, 7, 7> analytic = (block == 0 ? ja : jb) * plus_jac;
    const Vector8d x0 = x;
    for (int j = 0; j < 7; ++j) {
      const double h = 1e-6;
      Vector7d d = Vector7d::Zero();
      Vector7d rp, rm;
      d[j] = h;
      manifold.Plus(x0.data(), d.data(), x.data());
      cost->Evaluate(params, rp.data(), nullptr);
      d[j] = -h;
      manifold.Plus(x0.data(), d.data(), x.data());
      cost->Evaluate(params, rm.data(), nullptr);
      x = x0;
      const Vector7d numeric = (rp - rm) / (2 * h);
      EXPECT_LT((analytic.col(j) - numeric).norm(), 1e-5 * std::max(1.0, numeric.norm()))
          << "block " << block << " column " << j;
    }
  }
}

// The analytic-Jacobian Sim(3) edge: same residual as EdgeError, same tangent Jacobians
// (J * PlusJacobian) as its autodiff and as central finite differences, in several regimes
// (generic, measurement == estimate, tiny rotation, large rotation near pi).
TEST(Sim3EdgeCost, MatchesAutodiffAndFiniteDifferences) {
  auto rng = test::SeededRng(9);
  Matrix7d info = Matrix7d::Identity();
  info(0, 1) = info(1, 0) = 0.3;
  info(6, 6) = 4.0;
  const Matrix7d sqrt_info = SqrtInformation(info);
  Sim3Manifold manifold;
  const double regimes[][4] = {// pose t, pose r, pose s, measurement disagreement
                               {2.0, 1.0, 0.3, 0.2},
                               {2.0, 1.0, 0.3, 0.0},
                               {2.0, 1e-7, 1e-7, 1e-6},
                               {50.0, 2.8, 0.5, 0.5},
                               {50.0, 2.8, 0.5, 0.02}};  // series Jl (small log E)
  for (const auto& reg : regimes) {
    for (int trial = 0; trial < 20; ++trial) {
      const Sim3d a = Sim3d::Exp(RandomTangent(rng, reg[0], reg[1], reg[2]));
      const Sim3d b = Sim3d::Exp(RandomTangent(rng, reg[0], reg[1], reg[2]));
      const Sim3d z = Sim3d::Exp(RandomTangent(rng, reg[3], reg[3], reg[3] / 2)) * a.Inverse() * b;
      std::unique_ptr<ceres::CostFunction> autodiff(EdgeError::Create(z, sqrt_info));
      std::unique_ptr<ceres::CostFunction> analytic(Sim3EdgeCost::Create(z, sqrt_info));
      Vector8d av = a.ToVector(), bv = b.ToVector();
      const double* params[2] = {av.data(), bv.data()};
      Eigen::Matrix<double, 7, 8, Eigen::RowMajor> ja_ad, jb_ad, ja_an, jb_an;
      double* j_ad[2] = {ja_ad.data(), jb_ad.data()};
      double* j_an[2] = {ja_an.data(), jb_an.data()};
      Vector7d r_ad, r_an;
      ASSERT_TRUE(autodiff->Evaluate(params, r_ad.data(), j_ad));
      ASSERT_TRUE(analytic->Evaluate(params, r_an.data(), j_an));
      EXPECT_LT((r_ad - r_an).norm(), 1e-9 * std::max(1.0, r_ad.norm()));
      for (int block = 0; block < 2; ++block) {
        Vector8d& x = block == 0 ? av : bv;
        Eigen::Matrix<double, 8, 7, Eigen::RowMajor> plus_jac;
        manifold.PlusJacobian(x.data(), plus_jac.data());
        const Eigen::Matrix<double, 7, 7> t_ad = (block == 0 ? ja_ad : jb_ad) * plus_jac;
        const Eigen::Matrix<double, 7, 7> t_an = (block == 0 ? ja_an : jb_an) * plus_jac;
        EXPECT_LT((t_ad - t_an).norm(), 1e-7 * std::max(1.0, t_ad.norm()))
            << "block " << block << " regime t " << reg[0] << " r " << reg[1] << "\n"
            << t_ad << "\n\n"
            << t_an;
        // Central finite differences along the manifold.
        const Vector8d x0 = x;
        for (int j = 0; j < 7; ++j) {
          const double h = 1e-6;
          Vector7d d = Vector7d::Zero(), rp, rm;
          d[j] = h;
          manifold.Plus(x0.data(), d.data(), x.data());
          analytic->Evaluate(params, rp.data(), nullptr);
          d[j] = -h;
          manifold.Plus(x0.data(), d.data(), x.data());
          analytic->Evaluate(params, rm.data(), nullptr);
          x = x0;
          const Vector7d numeric = (rp - rm) / (2 * h);
          EXPECT_LT((t_an.col(j) - numeric).norm(), 1e-4 * std::max(1.0, numeric.norm()))
              << "block " << block << " column " << j;
        }
      }
    }
  }
}

TEST(EdgeError, SqrtInformationRejectsIndefinite) {
  Matrix7d info = Matrix7d::Identity();
  info(2, 2) = -1.0;
  EXPECT_THROW(SqrtInformation(info), std::invalid_argument);
  Matrix7d asym = Matrix7d::Identity();
  asym(0, 1) = 0.5;
  EXPECT_THROW(SqrtInformation(asym), std::invalid_argument);
  Matrix7d rank_deficient = Matrix7d::Zero();
  rank_deficient(0, 0) = 4.0;
  const Matrix7d s = SqrtInformation(rank_deficient);
  EXPECT_LT((s.transpose() * s - rank_deficient).norm(), 1e-12);
}

// Sim3EdgeCost's Bernoulli-series Jl against the exact Jet one, up to the series' limit
// (|omega|, |sigma| < 0.05) and with translations up to 100 units (they enter ad nilpotently).
TEST(Sim3EdgeCost, SeriesLogJacobianMatchesJetsUpToItsLimit) {
  auto rng = test::SeededRng(12);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int k = 0; k < 200; ++k) {
    const double rot = 0.0499 * (k % 10) / 9.0;
    Eigen::Vector3d axis(n(rng), n(rng), n(rng));
    jet::Vector7<double> xi;
    xi.head<3>() = 100.0 * (k % 7) / 6.0 * Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
    xi.segment<3>(3) = rot * axis.normalized();
    xi[6] = 0.0499 * std::sin(k);
    const Sim3d e_d = Sim3d::Exp(xi);
    jet::Sim3<double> e;
    e.rotation = e_d.rotation;
    e.translation = e_d.translation;
    e.scale = e_d.scale;
    const jet::Vector7<double> log = e.Log();
    const Matrix7d series = Sim3EdgeCost::LogJacobian(e, log);
    // The exact value: log(E exp(d)) differentiated with Jets.
    using J = ceres::Jet<double, 7>;
    jet::Sim3<J> ej;
    ej.rotation = e.rotation.cast<J>();
    ej.translation = e.translation.cast<J>();
    ej.scale = J(e.scale);
    jet::Vector7<J> d;
    for (int i = 0; i < 7; ++i) d[i] = J(0.0, i);
    const jet::Vector7<J> lj = (ej * jet::Sim3<J>::Exp(d)).Log();
    Matrix7d exact;
    for (int row = 0; row < 7; ++row) exact.row(row) = lj[row].v.transpose();
    EXPECT_LT((series - exact).cwiseAbs().maxCoeff(), 1e-10 * std::max(1.0, exact.norm()))
        << "k " << k << "\n"
        << series << "\n\n"
        << exact;
  }
}

}  // namespace
}  // namespace sparseloop
