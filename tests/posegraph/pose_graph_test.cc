// Pose graph on synthetic drifting trajectories with ground truth, outlier loops, g2o parsing,
// interpolation of non-keyframe poses and the direction-only loop constraint.
#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <sstream>
#include <string>

#include "loop_harness.h"
#include "posegraph/chain_reduction.h"
#include "posegraph/edge_error.h"
#include "posegraph/sim3_jet.h"
#include "sparseloop/core/error.h"
#include "sparseloop/posegraph/g2o.h"
#include "sparseloop/posegraph/interpolation.h"
#include "sparseloop/posegraph/pose_graph.h"
#include "test_util.h"

namespace sparseloop {
namespace {

// Two laps around a circle of radius 30 m (GT), and a raw monocular-like estimate that
// integrates the true relative motions with rotation, scale and translation drift.
struct Synthetic {
  std::vector<Sim3d> gt;
  std::vector<Sim3d> raw;
};

// `scale_bias`: the raw trajectory's log-scale drift per keyframe (plus 0.003 of noise).
Synthetic MakeSynthetic(int per_lap, double laps, uint64_t seed, double scale_bias = 0.002) {
  auto rng = test::SeededRng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  Synthetic s;
  const int n = static_cast<int>(per_lap * laps);
  const double radius = 30.0;
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * M_PI * i / per_lap;
    const Eigen::Vector3d p(radius * std::cos(a), radius * std::sin(a), 0.5 * std::sin(3 * a));
    // Camera looks along the tangent (z forward), y down.
    const Eigen::Vector3d fwd(-std::sin(a), std::cos(a), 0.0);
    const Eigen::Vector3d down(0, 0, -1);
    Eigen::Matrix3d r;
    r.col(2) = fwd;
    r.col(1) = down;
    r.col(0) = down.cross(fwd);
    s.gt.push_back(Sim3d(1.0, Eigen::Quaterniond(r), p));
  }
  s.raw.push_back(s.gt[0]);
  double log_scale = 0.0;
  for (int i = 1; i < n; ++i) {
    Sim3d rel = s.gt[i - 1].Inverse() * s.gt[i];
    Vector6d noise;
    for (int k = 0; k < 3; ++k) noise[k] = 0.01 * n01(rng);
    noise[3] = 0.002 * n01(rng);
    noise[4] = 0.002 + 0.002 * n01(rng);  // yaw-like bias: heading drift
    noise[5] = 0.002 * n01(rng);
    log_scale += scale_bias + 0.003 * n01(rng);  // scale drift
    const Rigid3d noisy = rel.ToRigid() * Rigid3d::Exp(noise);
    s.raw.push_back(s.raw.back() *
                    Sim3d(1.0, noisy.rotation, std::exp(log_scale) * noisy.translation));
  }
  return s;
}

PoseGraphOptions Plain() {
  PoseGraphOptions o;
  o.rejection = OutlierRejection::kNone;
  o.loop_loss = RobustLoss::kTrivial;
  return o;
}

// Loops between GT revisits within 3 m, at least 100 keyframes apart (the synthetic laps).
test::LoopHarnessOptions Revisits(int64_t query_stride, double outlier_fraction) {
  test::LoopHarnessOptions ho;
  ho.distance = 3.0;
  ho.min_gap = 100;
  ho.query_stride = query_stride;
  ho.outlier_fraction = outlier_fraction;
  return ho;
}

TEST(PoseGraph, CorrectsSyntheticSim3DriftWithLoops) {
  const Synthetic s = MakeSynthetic(150, 2.3, 1);
  auto rng = test::SeededRng(11);
  const test::LoopHarnessOptions ho = Revisits(5, 0.0);
  const test::HarnessLoops loops = test::MakeHarnessLoops(s.raw, s.gt, ho, rng);
  ASSERT_GE(loops.loops.size(), 10u);
  const double raw_ate = test::AlignedAte(s.raw, s.gt);
  const auto result = test::CorrectAndScore(s.raw, s.gt, loops.loops, PoseGraphOptions{});
  std::cerr << "synthetic: raw ATE " << raw_ate << " m, corrected " << result.ate << " m, "
            << result.summary.BriefReport() << "\n";
  EXPECT_NE(result.summary.status, PoseGraphStatus::kFailed);
  EXPECT_TRUE(result.summary.rejected_loops.empty());
  EXPECT_LT(result.ate, 0.2 * raw_ate);
}

TEST(PoseGraph, FalseLoopsAreRejectedAndDoNotPullTheMapApart) {
  const Synthetic s = MakeSynthetic(150, 2.3, 2);
  auto rng = test::SeededRng(12);
  const test::LoopHarnessOptions ho = Revisits(5, 0.2);
  const test::HarnessLoops loops = test::MakeHarnessLoops(s.raw, s.gt, ho, rng);
  const double raw_ate = test::AlignedAte(s.raw, s.gt);
  PoseGraphOptions pcm;  // default: PCM
  const auto r_pcm = test::CorrectAndScore(s.raw, s.gt, loops.loops, pcm);
  const auto r_plain = test::CorrectAndScore(s.raw, s.gt, loops.loops, Plain());
  std::cerr << "synthetic 20% false loops: raw " << raw_ate << ", PCM " << r_pcm.ate
            << ", plain LS " << r_plain.ate << "\n";
  EXPECT_LT(r_pcm.ate, 0.4 * raw_ate);
  EXPECT_GT(r_plain.ate, 2.0 * r_pcm.ate);
  // Every false loop is reported rejected by PCM; few true ones are lost.
  size_t false_kept = 0, true_rejected = 0;
  std::vector<bool> rejected(loops.loops.size(), false);
  for (size_t k : r_pcm.summary.rejected_loops) rejected[k] = true;
  for (size_t k = 0; k < loops.loops.size(); ++k) {
    if (loops.is_false[k] && !rejected[k]) ++false_kept;
    if (!loops.is_false[k] && rejected[k]) ++true_rejected;
  }
  EXPECT_EQ(false_kept, 0u);
  EXPECT_LE(true_rejected, loops.loops.size() / 5);
  ASSERT_EQ(r_pcm.summary.rejected_loops.size(), r_pcm.summary.rejected_loop_ids.size());
  for (size_t i = 0; i < r_pcm.summary.rejected_loops.size(); ++i) {
    const LoopConstraint& l = loops.loops[r_pcm.summary.rejected_loops[i]];
    EXPECT_EQ(r_pcm.summary.rejected_loop_ids[i].query, l.query_id);
    EXPECT_EQ(r_pcm.summary.rejected_loop_ids[i].match, l.match_id);
  }
}

// A heading bias of 2 deg per keyframe against the default odometry model (0.003 rad per step):
// one solve compromises and leaves most kept loops far outside their own covariance; the weight
// rounds re-solve with heavier kept loops until the median kept loop passes its check, and never
// keep a false loop. At 1 deg per keyframe only a minority is left inconsistent (4 of 8): one
// solve, and those loops are reported, not satisfied by weighting every loop up.
TEST(PoseGraph, WeightRoundsSatisfyKeptLoopsWhenOdometryClaimsTooMuch) {
  const int per_lap = 60;
  const Synthetic base = MakeSynthetic(per_lap, 1.5, 3);
  for (const double bias_deg : {1.0, 2.0}) {
    // Re-integrate with a strong heading bias and 0.5 % scale growth per keyframe.
    Synthetic s = base;
    std::vector<Sim3d> raw{s.gt[0]};
    for (size_t i = 1; i < s.gt.size(); ++i) {
      const Sim3d rel = s.gt[i - 1].Inverse() * s.gt[i];
      const Rigid3d biased =
          rel.ToRigid() *
          Rigid3d::Exp((Vector6d() << 0, 0, 0, 0, bias_deg * M_PI / 180.0, 0).finished());
      raw.push_back(raw.back() *
                    Sim3d(1.0, biased.rotation,
                          std::pow(1.005, static_cast<double>(i)) * biased.translation));
    }
    s.raw = raw;
    for (const double outliers : {0.0, 0.2}) {
      SCOPED_TRACE(::testing::Message() << bias_deg << " deg, " << outliers << " false");
      auto rng = test::SeededRng(21);
      test::LoopHarnessOptions ho = Revisits(4, outliers);
      ho.min_gap = 40;
      const test::HarnessLoops loops = test::MakeHarnessLoops(s.raw, s.gt, ho, rng);
      ASSERT_GE(loops.loops.size(), 5u);
      const double raw_ate = test::AlignedAte(s.raw, s.gt);
      PoseGraphOptions single;
      single.loop_weight_rounds = 0;
      const auto one = test::CorrectAndScore(s.raw, s.gt, loops.loops, single);
      const auto rounds = test::CorrectAndScore(s.raw, s.gt, loops.loops, PoseGraphOptions{});
      std::cerr << "heading bias " << bias_deg << " deg/kf, " << outliers * 100
                << " % false loops: raw ATE " << raw_ate << ", one solve " << one.ate
                << ", weight rounds " << rounds.ate << " (" << rounds.summary.solves
                << " solves, loops x" << rounds.summary.loop_weight_scale << ")\n";
      const auto inconsistent = [](const PoseGraphSummary& summary) {
        return std::count_if(summary.loop_checks.begin(), summary.loop_checks.end(),
                             [](const LoopResidualCheck& c) { return !c.consistent; });
      };
      const auto checked = static_cast<long>(one.summary.loop_checks.size());
      EXPECT_EQ(one.summary.solves, 1);
      EXPECT_EQ(one.summary.loop_weight_scale, 1.0);
      EXPECT_LT(rounds.ate, 0.4 * raw_ate);
      if (bias_deg < 1.5) {
        // A minority left inconsistent: reported, no rounds.
        EXPECT_GT(inconsistent(one.summary), 0);
        EXPECT_LE(2 * inconsistent(one.summary), checked);
        EXPECT_EQ(rounds.summary.solves, 1);
        EXPECT_EQ(inconsistent(rounds.summary), inconsistent(one.summary));
        continue;
      }
      // The premise: one solve leaves most kept loops unsatisfied.
      EXPECT_GT(2 * inconsistent(one.summary), checked);
      // The rounds: the median kept loop satisfied, the trajectory corrected further.
      EXPECT_LE(2 * inconsistent(rounds.summary), checked);
      EXPECT_GT(rounds.summary.solves, 1);
      EXPECT_GT(rounds.summary.loop_weight_scale, 1.0);
      EXPECT_LT(rounds.ate, one.ate);
      // The same loops are kept: no false one re-admitted.
      EXPECT_EQ(rounds.summary.rejected_loops, one.summary.rejected_loops);
      for (size_t k = 0; k < loops.loops.size(); ++k) {
        if (!loops.is_false[k]) continue;
        EXPECT_NE(std::find(rounds.summary.rejected_loops.begin(),
                            rounds.summary.rejected_loops.end(), k),
                  rounds.summary.rejected_loops.end())
            << "false loop " << k << " kept";
      }
    }
  }
}

// loop_weight_quantile: which kept loop decides the rounds. Three loops measured 2 m off with 100x
// their information among 99 (no PCM, so all are kept): one of them is left inconsistent by the
// solve. With the median deciding there is one solve and the loop is reported; with the worst
// deciding (1, the former rule) every loop is weighted up for it.
TEST(PoseGraph, WeightRoundsFollowTheQuantileNotTheWorstLoop) {
  const Synthetic s = MakeSynthetic(150, 2.3, 1);
  auto rng = test::SeededRng(5);
  test::HarnessLoops loops = test::MakeHarnessLoops(s.raw, s.gt, Revisits(2, 0.0), rng);
  ASSERT_GE(loops.loops.size(), 60u);
  for (size_t k = 3; k < loops.loops.size(); k += loops.loops.size() / 3) {
    LoopConstraint& l = loops.loops[k];
    l.match_from_query.translation += l.match_from_query.scale * Eigen::Vector3d(2.0, 0, 0);
    l.information *= 100.0;
  }
  PoseGraphOptions median;
  median.rejection = OutlierRejection::kNone;
  PoseGraphOptions worst = median;
  worst.loop_weight_quantile = 1.0;
  const auto m = test::CorrectAndScore(s.raw, s.gt, loops.loops, median);
  const auto w = test::CorrectAndScore(s.raw, s.gt, loops.loops, worst);
  const auto inconsistent =
      std::count_if(m.summary.loop_checks.begin(), m.summary.loop_checks.end(),
                    [](const LoopResidualCheck& c) { return !c.consistent; });
  EXPECT_GE(inconsistent, 1);
  EXPECT_LE(inconsistent, 3);
  EXPECT_EQ(m.summary.solves, 1);
  EXPECT_EQ(m.summary.loop_weight_scale, 1.0);
  EXPECT_GT(w.summary.solves, 1);
  EXPECT_GT(w.summary.loop_weight_scale, 1.0);
  PoseGraphOptions bad;
  bad.loop_weight_quantile = 0.0;
  EXPECT_THROW(bad.Check(), std::invalid_argument);
  bad.loop_weight_quantile = 1.5;
  EXPECT_THROW(bad.Check(), std::invalid_argument);
}

// Kimera-RPGO style: two consistent loops are kept, an inconsistent one is dropped.
TEST(Pcm, ConsistentLoopsKeptInconsistentDropped) {
  const Synthetic s = MakeSynthetic(100, 2.0, 3);
  std::vector<int64_t> ids(s.gt.size());
  for (size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<int64_t>(i);
  // Use the GT as "raw" so exact loops are perfectly consistent with odometry.
  PoseGraph graph = BuildOdometryGraph(ids, s.gt, VertexType::kSim3);
  auto exact = [&](int64_t q, int64_t m) {
    LoopConstraint l;
    l.query_id = q;
    l.match_id = m;
    l.match_from_query = s.gt[m].Inverse() * s.gt[q];
    l.information = LoopInformation(0.05, 0.01, 0.01);
    return l;
  };
  graph.AddLoop(exact(150, 50));
  graph.AddLoop(exact(170, 70));
  LoopConstraint bad = exact(160, 20);  // places 60 m apart
  bad.match_from_query = s.gt[60].Inverse() * s.gt[160];
  graph.AddLoop(bad);
  const std::vector<size_t> kept = graph.PcmConsistentLoops(PcmOptions{});
  EXPECT_EQ(kept, (std::vector<size_t>{0, 1}));
  const PoseGraphSummary summary = graph.Optimize(PoseGraphOptions{});
  ASSERT_EQ(summary.rejected_loops, std::vector<size_t>{2});
  EXPECT_EQ(summary.rejected_loop_ids[0], (LoopPair{160, 20}));
}

// BuildOdometryGraph with the caller's step covariances: those steps get the inverse as
// information and the caller flag, the others the model; a bad covariance names its keyframe.
TEST(PoseGraph, OdometryGraphTakesTheCallersStepCovariances) {
  const Synthetic s = MakeSynthetic(20, 1.0, 2);
  std::vector<int64_t> ids;
  for (size_t i = 0; i < s.raw.size(); ++i) ids.push_back(static_cast<int64_t>(100 + i));
  std::vector<std::optional<Eigen::Matrix<double, 6, 6>>> cov(ids.size());
  Eigen::Matrix<double, 6, 6> c = Eigen::Matrix<double, 6, 6>::Identity() * 0.04;
  c(0, 1) = c(1, 0) = 0.01;
  cov[3] = c;
  cov[7] = c * 2.0;
  const OdometryWeighting w;
  const PoseGraph graph = BuildOdometryGraph(ids, s.raw, VertexType::kSim3, w, cov);
  ASSERT_EQ(graph.edges().size(), ids.size() - 1);
  for (const PoseGraphEdge& e : graph.edges()) {
    const size_t i = static_cast<size_t>(e.to - 100);
    EXPECT_EQ(e.information_from_caller, cov[i].has_value()) << i;
    const Matrix7d expected =
        cov[i] ? w.InformationFromCovariance(*cov[i]) : w.Information(e.from_from_to);
    EXPECT_LT((e.information - expected).norm(), 1e-9 * expected.norm()) << i;
  }
  EXPECT_LT((graph.edges()[2].information.topLeftCorner<6, 6>().inverse() - c).norm(), 1e-12);
  cov[5] = -c;
  try {
    BuildOdometryGraph(ids, s.raw, VertexType::kSim3, w, cov);
    ADD_FAILURE() << "no error for a negative definite covariance";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("keyframe 105"), std::string::npos) << e.what();
  }
}

// PCM with the caller's odometry covariance (PoseGraphEdge::information_from_caller): with a
// per-step rotation noise of 2 and 4 deg (sigma) the default per-step model (0.01 rad) calls pairs
// of true loops inconsistent; with the covariance the caller states for that noise PCM keeps the
// true loops; a caller claiming 10x less than the truth makes PCM keep fewer. No false loop kept.
TEST(Pcm, CallerCovarianceReplacesTheModelForItsSteps) {
  for (const double sigma_deg : {2.0, 4.0}) {
    SCOPED_TRACE(sigma_deg);
    Synthetic s = MakeSynthetic(60, 2.5, 3);
    const double sigma = sigma_deg * M_PI / 180.0;
    auto noise_rng = test::SeededRng(5);
    std::normal_distribution<double> n01(0.0, 1.0);
    std::vector<Sim3d> raw{s.gt[0]};
    for (size_t i = 1; i < s.gt.size(); ++i) {
      const Sim3d rel = s.gt[i - 1].Inverse() * s.gt[i];
      Vector6d noise = Vector6d::Zero();
      for (int k = 3; k < 6; ++k) noise[k] = sigma * n01(noise_rng);
      const Rigid3d noisy = rel.ToRigid() * Rigid3d::Exp(noise);
      raw.push_back(raw.back() * Sim3d(1.0, noisy.rotation, noisy.translation));
    }
    s.raw = raw;
    auto rng = test::SeededRng(21);
    test::LoopHarnessOptions ho = Revisits(3, 0.2);
    ho.min_gap = 40;
    const test::HarnessLoops loops = test::MakeHarnessLoops(s.raw, s.gt, ho, rng);
    size_t n_true = 0;
    for (const bool f : loops.is_false) n_true += f ? 0 : 1;
    ASSERT_GE(n_true, 6u);
    ASSERT_GE(loops.loops.size() - n_true, 2u);
    auto kept_with = [&](bool caller, double stated_sigma) {
      PoseGraph graph(VertexType::kSim3);
      OdometryWeighting odometry;
      for (size_t i = 0; i < s.raw.size(); ++i) {
        graph.AddVertex(static_cast<int64_t>(i), s.raw[i]);
        if (i == 0) continue;
        PoseGraphEdge e;
        e.from = static_cast<int64_t>(i - 1);
        e.to = static_cast<int64_t>(i);
        e.from_from_to = s.raw[i - 1].Inverse() * s.raw[i];
        const double step = e.from_from_to.translation.norm();
        Eigen::Matrix<double, 6, 6> cov = Eigen::Matrix<double, 6, 6>::Zero();
        cov.diagonal() << Eigen::Vector3d::Constant(std::pow(0.05 * step, 2)),
            Eigen::Vector3d::Constant(stated_sigma * stated_sigma);
        e.information =
            caller ? odometry.InformationFromCovariance(cov) : odometry.Information(e.from_from_to);
        e.information_from_caller = caller;
        graph.AddEdge(e);
      }
      for (const LoopConstraint& l : loops.loops) graph.AddLoop(l);
      size_t true_kept = 0, false_kept = 0;
      for (const size_t k : graph.PcmConsistentLoops(PcmOptions{})) {
        (loops.is_false[k] ? false_kept : true_kept) += 1;
      }
      return std::pair{true_kept, false_kept};
    };
    const auto [model_true, model_false] = kept_with(false, sigma);
    const auto [caller_true, caller_false] = kept_with(true, sigma);
    const auto [tight_true, tight_false] = kept_with(true, 0.1 * sigma);
    std::cerr << "rotation noise " << sigma_deg << " deg/kf: " << n_true
              << " true loops, PCM keeps " << model_true << " with the model, " << caller_true
              << " with the caller's covariance, " << tight_true << " with 1/10 of it\n";
    EXPECT_EQ(model_false + caller_false + tight_false, 0u);
    EXPECT_LT(model_true, caller_true);
    EXPECT_GE(caller_true, n_true * 9 / 10);
    EXPECT_LT(tight_true, caller_true);
  }
}

// PCM's decisions in a full correction (CorrectAndScore) of harness loops: true loops kept,
// false loops kept, and the corrected ATE; printed with `label`.
struct PcmOutcome {
  size_t true_kept = 0, false_kept = 0, num_true = 0;
  double ate = 0.0;
};
PcmOutcome CorrectAndCount(const Synthetic& s, const test::HarnessLoops& loops,
                           const PoseGraphOptions& options, const std::string& label) {
  const auto r = test::CorrectAndScore(s.raw, s.gt, loops.loops, options);
  PcmOutcome c;
  c.ate = r.ate;
  std::vector<bool> rejected(loops.loops.size(), false);
  for (size_t k : r.summary.rejected_loops) rejected[k] = true;
  for (size_t k = 0; k < loops.loops.size(); ++k) {
    c.num_true += !loops.is_false[k];
    if (!rejected[k]) (loops.is_false[k] ? c.false_kept : c.true_kept) += 1;
  }
  std::cerr << label << ": " << c.true_kept << " of " << c.num_true << " true loops kept, "
            << c.false_kept << " false; raw ATE " << test::AlignedAte(s.raw, s.gt) << ", corrected "
            << c.ate << "\n";
  return c;
}

// A monocular scale drift with a bias (0.005 per keyframe: the scale grows 9x over the 3 laps,
// as 4x the renders' drift grows street00's 6x) and 20 % false loops. Two true loops far apart in
// time then miss each other by the scale change along their chains times the chains' length:
// PCM's random walk of step_scale_sigma does not hold it and, on the raw poses, keeps one group of
// true loops and rejects the others. With `pcm.scale_profile` (the default) the loops' own
// scales give the drift along the trajectory, the cycles are composed on the raw poses rescaled
// by it, and the true loops are kept together; the false ones still are not.
TEST(Pcm, ScaleProfileKeepsTrueLoopsUnderABiasedScaleDrift) {
  const Synthetic s = MakeSynthetic(150, 3.0, 6, 0.005);
  auto rng = test::SeededRng(16);
  const test::HarnessLoops loops = test::MakeHarnessLoops(s.raw, s.gt, Revisits(5, 0.2), rng);
  ASSERT_GE(loops.loops.size(), 40u);
  double max_log_scale = 0.0;
  for (const LoopConstraint& l : loops.loops)
    max_log_scale = std::max(max_log_scale, std::abs(std::log(l.match_from_query.scale)));
  EXPECT_GT(max_log_scale, 1.0);  // the premise: loops across an e-fold scale change
  const auto run = [&](bool profile) {
    PoseGraphOptions options;
    options.pcm.scale_profile = profile;
    return CorrectAndCount(s, loops, options,
                           "biased scale drift, profile " + std::to_string(profile));
  };
  const PcmOutcome raw = run(false), profiled = run(true);
  EXPECT_LT(raw.true_kept, raw.num_true * 3 / 4);  // the premise: the raw test splits them
  EXPECT_EQ(raw.false_kept, 0u);
  EXPECT_EQ(profiled.false_kept, 0u);
  EXPECT_GE(profiled.true_kept, profiled.num_true * 9 / 10);
  EXPECT_LT(profiled.ate, raw.ate);
}

// Loops that leave their relative scale free (PnP against the match's points, `se3_metric`: no
// depth on the query side) carry scale 1 in their pose. Under scale drift (this synthetic: about
// 0.2 % per keyframe, ~35 % between the laps) that scale is wrong by the drift between match and
// query, and the cycle of two such loops misses by that error times the match chain's length. PCM
// tests those translations with the scale's drift prior along the lever arm (the chain's scale
// variance between match and query) instead of at scale 1 with `pcm.free_scale_prior`: the true
// loops are kept (off, the default: most rejected), the 20 % false ones still are not.
TEST(Pcm, LoopsWithAFreeScaleAreTestedWithTheScalePriorNotAtScaleOne) {
  const Synthetic s = MakeSynthetic(150, 2.3, 4);
  auto rng = test::SeededRng(14);
  test::HarnessLoops loops = test::MakeHarnessLoops(s.raw, s.gt, Revisits(5, 0.2), rng);
  ASSERT_GE(loops.loops.size(), 15u);
  double max_scale_error = 0.0;
  for (LoopConstraint& l : loops.loops) {
    max_scale_error = std::max(max_scale_error, std::abs(std::log(l.match_from_query.scale)));
    l.match_from_query.scale = 1.0;  // what a PnP (se3_metric) loop reports
    l.information(6, 6) = 0.0;       // and its scale is not observed
    l.has_scale = false;
  }
  EXPECT_GT(max_scale_error, 0.2);  // the premise: scale 1 is far off for some loops
  const double raw_ate = test::AlignedAte(s.raw, s.gt);
  const auto run = [&](bool free_scale_prior) {
    PoseGraphOptions options;
    options.pcm.free_scale_prior = free_scale_prior;
    return CorrectAndCount(s, loops, options,
                           "free-scale loops, prior " + std::to_string(free_scale_prior));
  };
  const PcmOutcome at_one = run(false), with_prior = run(true);
  EXPECT_LT(at_one.true_kept, at_one.num_true / 2);  // the premise: at scale 1 most are lost
  EXPECT_EQ(at_one.false_kept, 0u);
  EXPECT_EQ(with_prior.false_kept, 0u);
  EXPECT_GE(with_prior.true_kept, with_prior.num_true * 4 / 5);
  EXPECT_LT(with_prior.ate, 0.4 * raw_ate);
}

// Perceptual aliasing as PCM's pairwise test cannot see it. A run of queries all match the same
// wrong place (the stretch `shift` keyframes along the first lap from the true one: 20 = 48 deg
// and 25 m, 30 = 72 deg and 37 m), each with the relative pose of the true place, and an
// information like a two-view Sim(3) without depths: tight except along one direction that
// trades rotation for translation (so every component's marginal variance is large). The pairwise
// test reads the marginal variances and calls the run consistent with every loop: all are kept.
// `pcm.odometry_check` (the default) tests each loop with its full information against its own
// odometry chain: the true loops are kept, the run is not. It sees what the odometry's drift does
// not cover: the raw poses drift ~0.11 deg per keyframe in heading (17 deg over the 150 keyframes
// of each loop), and at shift -20 the wrong place lies on the drift's side (48 less 17 deg): that
// run passes (printed, not asserted). (Odometry that drifts far beyond the
// model: PoseGraph.WeightRoundsSatisfyKeptLoopsWhenOdometryClaimsTooMuch, 1-2 deg per keyframe,
// where the calibration by the loops' median keeps the true loops.)
TEST(Pcm, OdometryCheckRejectsARunOfLoopsToTheWrongPlace) {
  const Synthetic s = MakeSynthetic(150, 2.3, 3);
  // Loops as loop_harness.h makes them (raw units, the local scales' ratio), exact.
  const std::vector<double> lambda = test::LocalScales(s.raw, s.gt, 5, 1.0);
  Vector7d ambiguous;  // translation and rotation together, raw units / rad
  ambiguous << 10.0, 10.0, 10.0, 1.0, 1.0, 1.0, 0.0;
  ambiguous.normalize();
  const Matrix7d two_view_information =
      (LoopInformation(0.1, 0.02, 0.02).inverse() + 1e4 * ambiguous * ambiguous.transpose())
          .inverse();
  for (const int shift : {20, -20, 30, -30}) {
    PoseGraph graph(VertexType::kSim3);
    for (size_t v = 0; v < s.raw.size(); ++v) graph.AddVertex(static_cast<int64_t>(v), s.raw[v]);
    const auto loop = [&](int64_t q, int64_t m, int64_t place) {
      const Sim3d gt_rel = s.gt[place].Inverse() * s.gt[q];  // the pose to `place`, said of m
      LoopConstraint l;
      l.query_id = q;
      l.match_id = m;
      l.match_from_query =
          Sim3d(lambda[m] / lambda[q], gt_rel.rotation, lambda[m] * gt_rel.translation);
      l.information = LoopInformation(0.1, 0.02, 0.02);
      return l;
    };
    std::vector<bool> is_false;
    for (int64_t q = 160; q <= 250; q += 10) {  // 10 true loops, 150 keyframes back
      graph.AddLoop(loop(q, q - 150, q - 150));
      is_false.push_back(false);
    }
    for (int64_t q = 255; q <= 265; q += 2) {  // 6 false loops, one run
      LoopConstraint l = loop(q, q - 150 + shift, q - 150);
      l.information = two_view_information;
      graph.AddLoop(l);
      is_false.push_back(true);
    }
    const auto count = [&](const PcmOptions& options) {
      std::pair<size_t, size_t> kept{0, 0};  // true, false
      for (size_t k : graph.PcmConsistentLoops(options)) (is_false[k] ? kept.second : kept.first)++;
      return kept;
    };
    PcmOptions pairwise;
    pairwise.odometry_check = false;
    const auto [pairwise_true, pairwise_false] = count(pairwise);
    const auto [checked_true, checked_false] = count(PcmOptions{});
    std::cerr << "shift " << shift << ": pairwise keeps " << pairwise_true << " true, "
              << pairwise_false << " false; with the odometry check " << checked_true << ", "
              << checked_false << "\n";
    EXPECT_EQ(pairwise_false, 6u) << shift;  // the premise: the run is kept with the true loops
    EXPECT_EQ(checked_true, 10u) << shift;
    if (shift == -20) continue;  // within the drift (see above): printed, not asserted
    EXPECT_EQ(checked_false, 0u) << shift;
  }
  PcmOptions bad;
  bad.odometry_check_confidence = 1.0;
  EXPECT_THROW(bad.Check(), std::invalid_argument);
}

// The incremental PCM (what Optimize uses) gives exactly the full recomputation's clique while
// the graph grows: vertices and loops appended between calls, false loops among them, the test's
// options changed and changed back (the cache must be rebuilt, not reused). With the scale
// profile the cached pairs are recomputed when the profile moves by more than 0.01 in log-scale,
// so the two could differ by a pair within that; on this run they do not.
TEST(Pcm, IncrementalEqualsFullRecomputation) {
  const Synthetic s = MakeSynthetic(150, 2.3, 5);
  auto rng = test::SeededRng(13);
  const test::LoopHarnessOptions ho = Revisits(2, 0.3);
  test::HarnessLoops loops = test::MakeHarnessLoops(s.raw, s.gt, ho, rng);
  ASSERT_GE(loops.loops.size(), 30u);
  // Loops in the order their query keyframe arrives, as a running system adds them.
  std::vector<size_t> order(loops.loops.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return std::max(loops.loops[a].query_id, loops.loops[a].match_id) <
           std::max(loops.loops[b].query_id, loops.loops[b].match_id);
  });
  PcmOptions strict;  // a different pairwise test: far fewer pairs pass it
  strict.confidence = 0.5;
  strict.step_translation_fraction = 0.005;
  strict.step_rotation_sigma_rad = 0.0005;
  strict.step_scale_sigma = 0.0005;
  strict.odometry_check = false;  // and without the single-loop test (its cache is rebuilt)
  PoseGraph graph(VertexType::kSim3);
  size_t next_loop = 0, calls = 0, rejected_somewhere = 0;
  for (size_t v = 0; v < s.raw.size(); ++v) {
    graph.AddVertex(static_cast<int64_t>(v), s.raw[v]);
    bool added = false;
    while (next_loop < order.size()) {
      const LoopConstraint& l = loops.loops[order[next_loop]];
      if (static_cast<size_t>(std::max(l.query_id, l.match_id)) > v) break;
      graph.AddLoop(l);
      ++next_loop;
      added = true;
    }
    if (!added) continue;
    const PcmOptions& o = (calls / 4) % 2 == 1 ? strict : PcmOptions{};
    const std::vector<size_t> incremental = graph.PcmConsistentLoopsIncremental(o);
    EXPECT_EQ(incremental, graph.PcmConsistentLoops(o))
        << "after " << graph.loops().size() << " loops, call " << calls;
    rejected_somewhere += graph.loops().size() - incremental.size();
    ++calls;
  }
  EXPECT_EQ(next_loop, order.size());
  EXPECT_GE(calls, 8u);               // several growth steps, both option sets twice
  EXPECT_GT(rejected_somewhere, 0u);  // the false loops made PCM reject something
}

// The one name table of each option enum (the config keys and the CLI read these).
TEST(PoseGraph, OptionEnumNamesLiveNextToTheirEnums) {
  EXPECT_STREQ(ToString(RobustLoss::kTrivial), "trivial");
  EXPECT_STREQ(ToString(RobustLoss::kHuber), "huber");
  EXPECT_STREQ(ToString(RobustLoss::kCauchy), "cauchy");
  EXPECT_STREQ(ToString(OutlierRejection::kNone), "none");
  EXPECT_STREQ(ToString(OutlierRejection::kPcm), "pcm");
  EXPECT_STREQ(ToString(VertexType::kSim3), "sim3");
  EXPECT_STREQ(ToString(VertexType::kFourDof), "4dof");
  EXPECT_STREQ(ToString(VertexType::kSe2), "se2");
}

TEST(PoseGraph, GaugeVertexStaysFixedAndOptionsAreChecked) {
  const Synthetic s = MakeSynthetic(60, 1.5, 4);
  std::vector<int64_t> ids(s.raw.size());
  for (size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<int64_t>(100 + i);
  PoseGraph graph = BuildOdometryGraph(ids, s.raw, VertexType::kSim3);
  LoopConstraint l;
  l.query_id = ids[70];
  l.match_id = ids[10];
  l.match_from_query = s.gt[10].Inverse() * s.gt[70];
  graph.AddLoop(l);
  graph.SetFixedVertex(ids[5]);
  const Sim3d before = graph.Pose(ids[5]);
  const PoseGraphSummary summary = graph.Optimize(PoseGraphOptions{});
  EXPECT_NE(summary.status, PoseGraphStatus::kFailed);
  EXPECT_LT(summary.final_cost, summary.initial_cost);
  EXPECT_LT((graph.Pose(ids[5]).ToVector() - before.ToVector()).norm(), 1e-12);
  // Vertices before the fixed one are tied to it by odometry only and stay; those inside the
  // loop move.
  EXPECT_LT((graph.Pose(ids[0]).ToVector() - s.raw[0].ToVector()).norm(), 1e-9);
  EXPECT_GT((graph.Pose(ids[40]).ToVector() - s.raw[40].ToVector()).norm(), 1e-3);

  PoseGraphOptions bad;
  bad.max_iterations = 0;
  EXPECT_THROW(graph.Optimize(bad), std::invalid_argument);
  EXPECT_THROW(graph.AddVertex(ids[0], Sim3d()), std::invalid_argument);
  LoopConstraint unknown = l;
  unknown.query_id = 99999;
  EXPECT_THROW(graph.AddLoop(unknown), std::invalid_argument);
  PoseGraph empty;
  EXPECT_EQ(empty.Optimize(PoseGraphOptions{}).status, PoseGraphStatus::kNothingToDo);
}

TEST(PoseGraph, Se3GraphKeepsUnitScale) {
  const Synthetic s = MakeSynthetic(60, 1.5, 5);
  std::vector<int64_t> ids(s.raw.size());
  std::vector<Sim3d> metric;
  for (size_t i = 0; i < ids.size(); ++i) {
    ids[i] = static_cast<int64_t>(i);
    metric.push_back(Sim3d(s.raw[i].ToRigid()));
  }
  PoseGraph graph = BuildOdometryGraph(ids, metric, VertexType::kSe3);
  LoopConstraint l;
  l.query_id = 70;
  l.match_id = 10;
  l.match_from_query = Sim3d((s.gt[10].Inverse() * s.gt[70]).ToRigid());
  graph.AddLoop(l);
  graph.Optimize(PoseGraphOptions{});
  for (int64_t id : ids) ASSERT_NEAR(graph.Pose(id).scale, 1.0, 1e-12);
}

TEST(G2o, MalformedFilesThrowFileErrorWithLine) {
  const std::pair<std::string, int> cases[] = {
      {"VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 0 0 0 0 0 0\n", 2},
      {"VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nEDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 1 0 0\n", 2},
      {"# comment\nVERTEX_SE3:QUAT 0 0 0 0 0 0 0 2\n", 2},
      {"VERTEX_SE2 0 0 0 0\nVERTEX_SE3:QUAT 1 0 0 0 0 0 0 1\n", 2},
      {"VERTEX_SE2 0 0 0 0\n\nFOO 1 2\n", 3},
      {"VERTEX_SE2 0 0 0 x\n", 1},
      {"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 0 1 0 0\n", 2},
      {"VERTEX_SE2 0 0 0 0 7\n", 1},
      // A BOM, "\r\n" and lone "\r" line ends: the line an editor shows.
      {"\xEF\xBB\xBFVERTEX_SE2 0 0 0 0\r\nVERTEX_SE2 1 1 0 0\rFOO 1 2\r", 3},
      // Coordinates beyond 1e12: every cost was inf and the solve "converged" on nan.
      {"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1e300 0 0\n", 2},
      {"VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 0 -2e12 0 0 0 0 1\n", 2},
      {"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1e13 0 0 1 0 0 1 0 1\n", 3},
  };
  for (const auto& [text, line] : cases) {
    std::istringstream in(text);
    try {
      ReadG2o(in, "bad.g2o");
      ADD_FAILURE() << "no error for:\n" << text;
    } catch (const FileError& e) {
      EXPECT_EQ(e.line(), line) << text << "\n" << e.what();
      EXPECT_EQ(e.file(), "bad.g2o");
    }
  }
  EXPECT_THROW(ReadG2o(test::TempDir() / "missing.g2o"), FileError);
}

TEST(G2o, Se2KnownAnswerAndChainedInitialisation) {
  // Edges only: vertices are chained from the lowest id.
  std::istringstream in(
      "EDGE_SE2 0 1 1 0 1.5707963267948966 1 0 0 1 0 1\n"
      "EDGE_SE2 1 2 1 0 0 1 0 0 1 0 1\n");
  const PoseGraph g = ReadG2o(in, "chain.g2o");
  ASSERT_EQ(g.num_vertices(), 3u);
  EXPECT_LT((g.Pose(1).translation - Eigen::Vector3d(1, 0, 0)).norm(), 1e-12);
  EXPECT_LT((g.Pose(2).translation - Eigen::Vector3d(1, 1, 0)).norm(), 1e-12);
  std::stringstream out;
  WriteG2o(out, g);
  const PoseGraph again = ReadG2o(out, "again.g2o");
  EXPECT_LT((again.Pose(2).translation - Eigen::Vector3d(1, 1, 0)).norm(), 1e-12);
  EXPECT_EQ(again.edges()[0].information(5, 5), 1.0);
}

TEST(Interpolation, KeyframesGetTheirCorrectionAndConstantDeltaIsExact) {
  auto rng = test::SeededRng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  auto random_sim3 = [&] {
    Vector7d t;
    for (int i = 0; i < 7; ++i) t[i] = (i == 6 ? 0.2 : 1.0) * n01(rng);
    return Sim3d::Exp(t);
  };
  std::vector<StampedSim3> raw_kf, corrected_kf, frames;
  const Sim3d delta = random_sim3();
  for (int k = 0; k < 5; ++k) {
    const Sim3d p = random_sim3();
    raw_kf.push_back({1.0 * k, p});
    corrected_kf.push_back({1.0 * k, delta * p});
  }
  for (int f = -2; f < 12; ++f) frames.push_back({0.4 * f, random_sim3()});
  const auto out = CorrectFramePoses(raw_kf, corrected_kf, frames);
  ASSERT_EQ(out.size(), frames.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    const Sim3d expected = delta * frames[i].world_from_cam;
    EXPECT_LT((out[i].world_from_cam.ToMatrix4() - expected.ToMatrix4()).norm(), 1e-9);
  }
  // Varying delta: at keyframe times the corrected keyframe pose is returned exactly, midway the
  // geodesic midpoint of the two deltas is applied.
  corrected_kf[2].world_from_cam = random_sim3() * raw_kf[2].world_from_cam;
  const auto at_kf = CorrectFramePoses(raw_kf, corrected_kf, raw_kf);
  for (size_t k = 0; k < raw_kf.size(); ++k) {
    EXPECT_LT(
        (at_kf[k].world_from_cam.ToMatrix4() - corrected_kf[k].world_from_cam.ToMatrix4()).norm(),
        1e-9);
  }
  const Sim3d d1 = corrected_kf[1].world_from_cam * raw_kf[1].world_from_cam.Inverse();
  const Sim3d d2 = corrected_kf[2].world_from_cam * raw_kf[2].world_from_cam.Inverse();
  const Sim3d mid = InterpolateSim3(d1, d2, 0.5);
  // The midpoint is equidistant from both ends on the manifold.
  EXPECT_NEAR((d1.Inverse() * mid).Log().norm(), (mid.Inverse() * d2).Log().norm(), 1e-9);
  const auto at_mid = CorrectFramePoses(raw_kf, corrected_kf, {{1.5, raw_kf[0].world_from_cam}});
  EXPECT_LT(
      (at_mid[0].world_from_cam.ToMatrix4() - (mid * raw_kf[0].world_from_cam).ToMatrix4()).norm(),
      1e-9);
  EXPECT_THROW(CorrectFramePoses(raw_kf, {}, frames), std::invalid_argument);
}

TEST(DirectionLoop, MagnitudeFromLocalStepAndNoScaleInformation) {
  const Eigen::Quaterniond rot(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()));
  const Eigen::Vector3d dir = Eigen::Vector3d(1, 2, 2) / 3.0;
  DirectionLoopOptions o;
  o.baseline_in_steps = 2.0;
  const LoopConstraint l =
      MakeLoopConstraintFromDirection(10, 2, Sim3d(), Sim3d(), rot, dir, 0.5, o);
  EXPECT_FALSE(l.has_scale);
  EXPECT_EQ(l.query_id, 10);
  EXPECT_EQ(l.match_id, 2);
  EXPECT_LT((l.match_from_query.translation - 1.0 * dir).norm(), 1e-12);
  EXPECT_NEAR(l.match_from_query.scale, 1.0, 1e-15);
  EXPECT_EQ(l.information(6, 6), 0.0);
  // Less information along the direction than across it.
  const Eigen::Matrix3d it = l.information.topLeftCorner<3, 3>();
  const Eigen::Vector3d perp = dir.cross(Eigen::Vector3d::UnitX()).normalized();
  EXPECT_LT(dir.dot(it * dir), perp.dot(it * perp));
  EXPECT_THROW(MakeLoopConstraintFromDirection(10, 2, Sim3d(), Sim3d(), rot, 2 * dir, 0.5, o),
               std::invalid_argument);
}

// ---- Chain reduction (PoseGraphOptions::reduce_chains, src/posegraph/chain_reduction.h) ----

std::vector<std::array<size_t, 2>> EdgeEnds(const PoseGraph& g) {
  std::vector<std::array<size_t, 2>> ends;
  for (const PoseGraphEdge& e : g.edges()) {
    ends.push_back({static_cast<size_t>(e.from), static_cast<size_t>(e.to)});
  }
  return ends;
}

double PoseDistance(const Sim3d& a, const Sim3d& b) {
  return (a.ToMatrix4() - b.ToMatrix4()).cwiseAbs().maxCoeff();
}

TEST(ChainReduction, KeepsLoopEndsAndGaugeCutsLongChainsAndComposesExactly) {
  const Synthetic s = MakeSynthetic(50, 2.0, 3);  // 100 keyframes
  std::vector<int64_t> ids(s.raw.size());
  std::iota(ids.begin(), ids.end(), 0);
  const PoseGraph g = BuildOdometryGraph(ids, s.raw, VertexType::kSim3);
  std::vector<bool> keep(ids.size(), false);
  for (size_t v : {0, 5, 30, 60, 90}) keep[v] = true;
  const internal::ChainReduction red = internal::ReduceChains(g.edges(), EdgeEnds(g), keep, 8);
  // Kept: the five, the last vertex (one edge) and the cuts of 5-30, 30-60, 60-90 at 8 steps.
  const std::vector<size_t> expected_kept = {0,  5,  13, 21, 29, 30, 38, 46,
                                             54, 60, 68, 76, 84, 90, 98, 99};
  std::vector<size_t> kept;
  for (size_t v = 0; v < ids.size(); ++v) {
    if (red.kept[v]) kept.push_back(v);
  }
  EXPECT_EQ(kept, expected_kept);
  EXPECT_EQ(red.num_kept, expected_kept.size());
  // Every vertex is kept or inside exactly one chain; every edge is direct or one chain step.
  std::vector<int> covered(ids.size(), 0);
  size_t steps = red.direct_edges.size();
  for (const internal::ReducedChain& c : red.chains) {
    EXPECT_NE(c.from, c.to);
    EXPECT_TRUE(red.kept[c.from] && red.kept[c.to]);
    EXPECT_LE(c.steps.size(), 8u);
    EXPECT_EQ(c.steps.size(), c.interior.size() + 1);
    EXPECT_EQ(c.step_edges.size(), c.steps.size());
    EXPECT_EQ(c.step_reversed.size(), c.steps.size());
    for (size_t v : c.interior) ++covered[v];
    steps += c.steps.size();
    // The composed measurement is the raw relative pose between the chain's ends.
    EXPECT_LT(PoseDistance(FromJetSim3(c.from_from_to), s.raw[c.from].Inverse() * s.raw[c.to]),
              1e-9);
  }
  EXPECT_EQ(steps, g.edges().size());
  for (size_t v = 0; v < ids.size(); ++v) EXPECT_EQ(covered[v] + (red.kept[v] ? 1 : 0), 1) << v;
  EXPECT_THROW(internal::ReduceChains(g.edges(), EdgeEnds(g), keep, 0), std::invalid_argument);

  // A ring of chain vertices (no kept vertex at all) keeps one of them and reverses edges whose
  // direction is against the walk; a vertex with three edges is kept; so are the ends of an edge
  // without full-rank information.
  PoseGraph ring(VertexType::kSim3);
  for (int i = 0; i < 12; ++i) ring.AddVertex(i, s.raw[i]);
  for (int i = 0; i < 12; ++i) {
    PoseGraphEdge e;
    const bool reversed = i % 3 == 1;
    e.from = reversed ? (i + 1) % 12 : i;
    e.to = reversed ? i : (i + 1) % 12;
    e.from_from_to = s.raw[e.from].Inverse() * s.raw[e.to];
    ring.AddEdge(e);
  }
  const internal::ChainReduction rr =
      internal::ReduceChains(ring.edges(), EdgeEnds(ring), std::vector<bool>(12, false), 100);
  EXPECT_EQ(rr.num_kept, 2u);  // the ring's start and the vertex that closes it
  ASSERT_EQ(rr.chains.size(), 1u);
  EXPECT_EQ(rr.direct_edges.size(), 1u);
  const internal::ReducedChain& c = rr.chains[0];
  EXPECT_LT(PoseDistance(FromJetSim3(c.from_from_to), s.raw[c.from].Inverse() * s.raw[c.to]), 1e-9);
  PoseGraph branch = ring;
  PoseGraphEdge extra;
  extra.from = 3;
  extra.to = 8;
  extra.from_from_to = s.raw[3].Inverse() * s.raw[8];
  extra.information.diagonal()[6] = 0.0;  // rank-deficient: cannot be chained
  branch.AddEdge(extra);
  const internal::ChainReduction rb =
      internal::ReduceChains(branch.edges(), EdgeEnds(branch), std::vector<bool>(12, false), 100);
  EXPECT_TRUE(rb.kept[3] && rb.kept[8]);
  EXPECT_EQ(std::count(rb.direct_edges.begin(), rb.direct_edges.end(), 12u), 1);
}

// The composed edge's covariance is the first-order propagation of the edges' covariances: the
// sample covariance of log(Z^-1 * prod_i step_i) with each edge's measurement perturbed as
// Z_e exp(e), e ~ N(0, Sigma_e), agrees with it. Every third edge points against the chain (its
// step is the inverse measurement). A wrong adjoint, or a transport in the wrong direction, is off
// by far more than the sampling error.
TEST(ChainReduction, ComposedCovarianceMatchesSampledChains) {
  const Synthetic s = MakeSynthetic(40, 1.0, 4);
  const int n = 9;
  OdometryWeighting w;
  w.translation_fraction = 0.01;
  w.rotation_sigma_rad = 0.003;
  w.scale_sigma = 0.004;
  PoseGraph g(VertexType::kSim3);
  for (int i = 0; i < n; ++i) g.AddVertex(i, s.raw[i]);
  for (int i = 0; i + 1 < n; ++i) {
    PoseGraphEdge e;
    e.from = i % 3 == 1 ? i + 1 : i;
    e.to = i % 3 == 1 ? i : i + 1;
    e.from_from_to = s.raw[e.from].Inverse() * s.raw[e.to];
    e.information = w.Information(e.from_from_to);
    e.information(3, 3) *= 4.0;  // anisotropic rotation: the transport matters
    g.AddEdge(e);
  }
  std::vector<bool> keep(n, false);
  keep[0] = true;
  const internal::ChainReduction red = internal::ReduceChains(g.edges(), EdgeEnds(g), keep, 100);
  ASSERT_EQ(red.chains.size(), 1u);
  const internal::ReducedChain& c = red.chains[0];
  ASSERT_EQ(c.steps.size(), 8u);
  auto rng = test::SeededRng(5);
  std::normal_distribution<double> n01(0.0, 1.0);
  const int samples = 20000;
  Matrix7d sample_cov = Matrix7d::Zero();
  for (int k = 0; k < samples; ++k) {
    jet::Sim3<double> product;
    for (const PoseGraphEdge& edge : g.edges()) {
      const Eigen::Matrix<double, 7, 1> sd = edge.information.diagonal().cwiseInverse().cwiseSqrt();
      jet::Vector7<double> e;
      for (int d = 0; d < 7; ++d) e[d] = sd[d] * n01(rng);
      const jet::Sim3<double> measured = ToJetSim3(edge.from_from_to) * jet::Sim3<double>::Exp(e);
      product = product * (edge.from < edge.to ? measured : measured.Inverse());
    }
    const jet::Vector7<double> x = (c.from_from_to.Inverse() * product).Log();
    sample_cov += x * x.transpose() / samples;
  }
  // Whitened: S * sample_cov * S^T should be the identity.
  const Matrix7d whitened = c.sqrt_information * sample_cov * c.sqrt_information.transpose();
  std::cerr << "chain covariance: max |S C S^T - I| = "
            << (whitened - Matrix7d::Identity()).cwiseAbs().maxCoeff() << "\n";
  EXPECT_LT((whitened - Matrix7d::Identity()).cwiseAbs().maxCoeff(), 0.06);
  // The rotation and scale uncertainty of the steps adds to the translation's (lever arm): more
  // than the eight steps' own translation variances.
  const Matrix7d cov = (c.sqrt_information.transpose() * c.sqrt_information).inverse();
  const double step = (s.raw[0].Inverse() * s.raw[1]).translation.norm();
  EXPECT_GT(cov(0, 0), 1.5 * 8 * std::pow(0.01 * step, 2));
}

// The reduced solve against the full one on a two-lap drifting Sim(3) trajectory: the same
// corrected trajectory up to a small fraction of the correction, the same cost of the full graph,
// with a fraction of the vertices in the solve. max_chain_length = 1 solves the full problem.
TEST(ChainReduction, ReducedSolveMatchesTheFullSolve) {
  const Synthetic s = MakeSynthetic(150, 2.3, 1);
  auto rng = test::SeededRng(11);
  const test::HarnessLoops loops = test::MakeHarnessLoops(s.raw, s.gt, Revisits(20, 0.0), rng);
  ASSERT_GE(loops.loops.size(), 5u);
  std::vector<int64_t> ids(s.raw.size());
  std::iota(ids.begin(), ids.end(), 0);
  const auto solve = [&](bool reduce, int max_chain, PoseGraphSummary* summary) {
    PoseGraph g = BuildOdometryGraph(ids, s.raw, VertexType::kSim3);
    for (const auto& l : loops.loops) g.AddLoop(l);
    PoseGraphOptions o = Plain();
    o.reduce_chains = reduce;
    o.max_chain_length = max_chain;
    o.function_tolerance = 1e-10;  // compare minima, not stopping points
    *summary = g.Optimize(o);
    std::vector<Sim3d> out;
    for (int64_t id : ids) out.push_back(g.Pose(id));
    return out;
  };
  PoseGraphSummary s_full, s_red, s_one, s_long;
  const std::vector<Sim3d> full = solve(false, 8, &s_full);
  const std::vector<Sim3d> red = solve(true, 8, &s_red);
  const std::vector<Sim3d> one = solve(true, 1, &s_one);
  const std::vector<Sim3d> lng = solve(true, 1000, &s_long);
  double correction = 0.0, diff = 0.0, diff_one = 0.0, diff_long = 0.0;
  for (size_t i = 0; i < ids.size(); ++i) {
    correction = std::max(correction, (full[i].translation - s.raw[i].translation).norm());
    diff = std::max(diff, (red[i].translation - full[i].translation).norm());
    diff_one = std::max(diff_one, (one[i].translation - full[i].translation).norm());
    diff_long = std::max(diff_long, (lng[i].translation - full[i].translation).norm());
  }
  std::cerr << "chain reduction: correction " << correction << " m; max difference to the full "
            << "solve " << diff << " m (chains <= 8), " << diff_long << " m (unbounded), "
            << diff_one << " m (chains of 1); solved vertices " << s_red.num_solved_vertices
            << " / " << s_full.num_solved_vertices << "; full-graph cost " << s_full.final_cost
            << " vs " << s_red.final_cost << " (initial " << s_full.initial_cost << " vs "
            << s_red.initial_cost << ")\n";
  EXPECT_GT(correction, 5.0);
  EXPECT_EQ(s_full.num_solved_vertices, ids.size());
  EXPECT_LT(s_red.num_solved_vertices, ids.size() / 4);
  EXPECT_EQ(s_one.num_solved_vertices, ids.size());
  EXPECT_LT(diff_one, 1e-6);
  // Measured: 4.6e-5 and 3.3e-4 of the correction (1.9 / 13 mm of 40 m).
  EXPECT_LT(diff, 1e-4 * correction);
  EXPECT_LT(diff_long, 1e-3 * correction);
  EXPECT_LT(diff, diff_long);  // shorter chains, smaller linearisation error
  EXPECT_NEAR(s_red.initial_cost, s_full.initial_cost, 1e-9 * s_full.initial_cost);
  EXPECT_GE(s_red.final_cost, s_full.final_cost * (1 - 1e-9));  // the full solve is the minimum
  EXPECT_LT(s_red.final_cost, s_full.final_cost * (1 + 1e-4));
  EXPECT_LT(test::AlignedAte(red, s.gt), 1.01 * test::AlignedAte(full, s.gt));
}

}  // namespace
}  // namespace sparseloop
