#pragma once
// Test harness: loop constraints as a monocular vSLAM would measure them, built from ground truth.
//
// Given raw (drifting, up-to-scale) keyframe poses and the matching ground-truth poses, a loop
// between query q and match m (GT positions closer than `distance`, index gap >= `min_gap`) gets
//   match_from_query = Sim3(lambda_m / lambda_q, R_m^T R_q, lambda_m * R_m^T (p_q - p_m)) * noise
// where lambda_k is the raw trajectory's local scale (raw units per metre, from the path length
// over a window around k): the translation is expressed in the match keyframe's raw units and the
// scale maps the query's local map scale to the match's, exactly what a Sim(3) loop solver on the
// two local maps would return. False loops are random pairs with random relative poses.
#include <random>
#include <vector>

#include "sparseloop/eval/align.h"
#include "sparseloop/posegraph/pose_graph.h"

namespace sparseloop::test {

struct LoopHarnessOptions {
  double distance = 5.0;      // GT metres
  int64_t min_gap = 100;      // keyframes
  int64_t query_stride = 10;  // keep one loop per this many query keyframes
  int scale_window = 5;       // keyframes each side for the local scale
  double rotation_noise_rad = 0.01;
  double translation_noise = 0.05;  // fraction of the local raw step length
  double scale_noise = 0.01;        // log-scale
  double outlier_fraction = 0.0;    // replace this fraction of loops by false ones
};

inline std::vector<double> LocalScales(const std::vector<Sim3d>& raw, const std::vector<Sim3d>& gt,
                                       int window) {
  const int n = static_cast<int>(raw.size());
  std::vector<double> raw_len(n, 0.0), gt_len(n, 0.0);
  for (int i = 1; i < n; ++i) {
    raw_len[i] = raw_len[i - 1] + (raw[i].translation - raw[i - 1].translation).norm();
    gt_len[i] = gt_len[i - 1] + (gt[i].translation - gt[i - 1].translation).norm();
  }
  std::vector<double> out(n, 1.0);
  for (int i = 0; i < n; ++i) {
    int a = std::max(0, i - window), b = std::min(n - 1, i + window);
    double g = gt_len[b] - gt_len[a];
    double r = raw_len[b] - raw_len[a];
    while ((g < 1e-6 || r < 1e-9) && (a > 0 || b < n - 1)) {  // standing still: widen
      a = std::max(0, a - window);
      b = std::min(n - 1, b + window);
      g = gt_len[b] - gt_len[a];
      r = raw_len[b] - raw_len[a];
    }
    out[i] = g > 1e-6 && r > 1e-9 ? r / g : 1.0;
  }
  return out;
}

struct HarnessLoops {
  std::vector<LoopConstraint> loops;
  std::vector<bool> is_false;
};

inline HarnessLoops MakeHarnessLoops(const std::vector<Sim3d>& raw, const std::vector<Sim3d>& gt,
                                     const LoopHarnessOptions& o, std::mt19937_64& rng) {
  const std::vector<double> lambda = LocalScales(raw, gt, o.scale_window);
  std::normal_distribution<double> n01(0.0, 1.0);
  const int64_t n = static_cast<int64_t>(raw.size());
  HarnessLoops out;
  int64_t last_query = -o.query_stride;
  for (int64_t q = 0; q < n; ++q) {
    if (q - last_query < o.query_stride) continue;
    int64_t best = -1;
    double best_d = o.distance;
    for (int64_t m = 0; m + o.min_gap <= q; ++m) {
      const double d = (gt[q].translation - gt[m].translation).norm();
      if (d < best_d) {
        best_d = d;
        best = m;
      }
    }
    if (best < 0) continue;
    last_query = q;
    const int64_t m = best;
    const Sim3d gt_rel = gt[m].Inverse() * gt[q];  // metric
    const double step = m + 1 < n ? (raw[m + 1].translation - raw[m].translation).norm() : 1.0;
    Vector7d noise;
    for (int i = 0; i < 3; ++i) noise[i] = o.translation_noise * std::max(step, 1e-3) * n01(rng);
    for (int i = 3; i < 6; ++i) noise[i] = o.rotation_noise_rad * n01(rng);
    noise[6] = o.scale_noise * n01(rng);
    LoopConstraint loop;
    loop.query_id = q;
    loop.match_id = m;
    loop.match_from_query =
        Sim3d(lambda[m] / lambda[q], gt_rel.rotation, lambda[m] * gt_rel.translation) *
        Sim3d::Exp(noise);
    const double sigma_t = std::max(o.translation_noise * step, 1e-3) * 2.0;
    loop.information = LoopInformation(sigma_t, 2.0 * o.rotation_noise_rad, 2.0 * o.scale_noise);
    out.loops.push_back(loop);
    out.is_false.push_back(false);
  }
  // Replace a fraction of the loops by false ones: random pairs, random relative poses.
  const size_t num_false = static_cast<size_t>(o.outlier_fraction * out.loops.size() + 0.5);
  std::uniform_int_distribution<int64_t> pick(0, n - 1);
  std::vector<size_t> order(out.loops.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), rng);
  for (size_t k = 0; k < num_false && k < order.size(); ++k) {
    LoopConstraint& loop = out.loops[order[k]];
    int64_t q = 0, m = 0;
    while (q - m < o.min_gap) {
      q = pick(rng);
      m = pick(rng);
      if (q < m) std::swap(q, m);
    }
    const double step = (raw[m + 1].translation - raw[m].translation).norm();
    Vector7d t;
    for (int i = 0; i < 3; ++i) t[i] = 3.0 * std::max(step, 1e-3) * n01(rng);
    for (int i = 3; i < 6; ++i) t[i] = 0.5 * n01(rng);
    t[6] = 0.1 * n01(rng);
    loop.query_id = q;
    loop.match_id = m;
    loop.match_from_query = Sim3d::Exp(t);
    out.is_false[order[k]] = true;
  }
  return out;
}

// Sim(3)-aligned ATE RMSE of positions (evo_ape -as equivalent).
inline double AlignedAte(const std::vector<Sim3d>& est, const std::vector<Sim3d>& gt,
                         Alignment alignment = Alignment::kSim3) {
  std::vector<Eigen::Vector3d> e, g;
  for (size_t i = 0; i < est.size(); ++i) {
    e.push_back(est[i].translation);
    g.push_back(gt[i].translation);
  }
  return Umeyama(e, g, alignment).rms_residual;
}

struct CorrectionResult {
  double ate = 0.0;
  PoseGraphSummary summary;
};

// Builds the odometry graph from `raw`, adds `loops`, optimises with `options`, returns the
// aligned ATE of the corrected keyframe poses.
inline CorrectionResult CorrectAndScore(const std::vector<Sim3d>& raw, const std::vector<Sim3d>& gt,
                                        const std::vector<LoopConstraint>& loops,
                                        const PoseGraphOptions& options,
                                        const OdometryWeighting& weighting = {}) {
  std::vector<int64_t> ids(raw.size());
  for (size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<int64_t>(i);
  PoseGraph graph = BuildOdometryGraph(ids, raw, VertexType::kSim3, weighting);
  for (const auto& l : loops) graph.AddLoop(l);
  CorrectionResult r;
  r.summary = graph.Optimize(options);
  std::vector<Sim3d> corrected;
  for (int64_t id : ids) corrected.push_back(graph.Pose(id));
  r.ate = AlignedAte(corrected, gt);
  return r;
}

}  // namespace sparseloop::test
