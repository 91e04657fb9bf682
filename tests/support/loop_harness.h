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
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "sparseloop/eval/align.h"
#include "sparseloop/eval/associate.h"
#include "sparseloop/io/trajectory_io.h"
#include "sparseloop/posegraph/pose_graph.h"

namespace sparseloop::test {

struct LoopHarnessOptions {
  double distance = 5.0;  // GT metres
  // GT relative rotation below which the two keyframes see the same scene (rad); a place is only
  // recognised when the camera looks the same way.
  double max_rotation_rad = 3.2;
  int64_t min_gap = 100;      // keyframes
  int64_t query_stride = 10;  // keep one loop per this many query keyframes
  int scale_window = 5;       // keyframes each side for the local scale (grown, see LocalScales)
  double scale_min_extent = 1.0;  // GT metres: minimum RMS spread of the local-scale window
  double rotation_noise_rad = 0.01;
  double translation_noise = 0.05;  // fraction of the local raw step length
  double scale_noise = 0.01;        // log-scale
  double outlier_fraction = 0.0;    // replace this fraction of loops by false ones
  bool add_noise = true;  // false: exact measurements (the information still uses the sigmas)
};

// The raw trajectory's local scale at each keyframe (raw units per GT metre): the scale of the
// Sim(3) (Umeyama) alignment of raw onto GT positions over a window of keyframes around it, grown
// until the GT positions in it spread over at least `min_extent` metres (RMS about their mean).
// This is what a local map's scale is; a ratio of path lengths is not (on slow or hovering
// segments the raw jitter inflates the raw path length many times).
inline std::vector<double> LocalScales(const std::vector<Sim3d>& raw, const std::vector<Sim3d>& gt,
                                       int window, double min_extent) {
  const int n = static_cast<int>(raw.size());
  std::vector<double> out(n, 1.0);
  for (int i = 0; i < n; ++i) {
    int a = std::max(0, i - window), b = std::min(n - 1, i + window);
    while (true) {
      std::vector<Eigen::Vector3d> e, g;
      for (int k = a; k <= b; ++k) {
        e.push_back(raw[k].translation);
        g.push_back(gt[k].translation);
      }
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (const auto& p : g) mean += p;
      mean /= static_cast<double>(g.size());
      double spread = 0.0;
      for (const auto& p : g) spread += (p - mean).squaredNorm();
      spread = std::sqrt(spread / static_cast<double>(g.size()));
      if (spread >= min_extent || (a == 0 && b == n - 1)) {
        const AlignmentResult al = Umeyama(g, e, Alignment::kSim3);  // raw_from_gt
        if (al.status != AlignmentStatus::kTooFewPoints && al.gt_from_est.scale > 0) {
          out[i] = al.gt_from_est.scale;
        }
        break;
      }
      a = std::max(0, a - window);
      b = std::min(n - 1, b + window);
    }
  }
  return out;
}

struct HarnessLoops {
  std::vector<LoopConstraint> loops;
  std::vector<bool> is_false;
};

// `scales`, when given (one per keyframe, raw units per GT metre: a render's raw_scale.txt), are
// the raw trajectory's exact local scales; otherwise LocalScales estimates them.
inline HarnessLoops MakeHarnessLoops(const std::vector<Sim3d>& raw, const std::vector<Sim3d>& gt,
                                     const LoopHarnessOptions& o, std::mt19937_64& rng,
                                     const std::vector<double>* scales = nullptr) {
  const std::vector<double> lambda =
      scales ? *scales : LocalScales(raw, gt, o.scale_window, o.scale_min_extent);
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
      if (d < best_d && Eigen::AngleAxisd(gt[m].rotation.inverse() * gt[q].rotation).angle() <
                            o.max_rotation_rad) {
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
    if (!o.add_noise) noise.setZero();
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
                                        const OdometryWeighting& weighting = {},
                                        VertexType vertex_type = VertexType::kSim3) {
  std::vector<int64_t> ids(raw.size());
  for (size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<int64_t>(i);
  PoseGraph graph = BuildOdometryGraph(ids, raw, vertex_type, weighting);
  for (const auto& l : loops) graph.AddLoop(l);
  CorrectionResult r;
  r.summary = graph.Optimize(options);
  std::vector<Sim3d> corrected;
  for (int64_t id : ids) corrected.push_back(graph.Pose(id));
  r.ate = AlignedAte(corrected, gt);
  return r;
}

// A real drifting trajectory: keyframes of the raw vSLAM output with the associated GT pose.
struct DriftCase {
  std::string name;
  std::vector<Sim3d> raw;  // keyframes
  std::vector<Sim3d> gt;   // associated GT of each keyframe
  LoopHarnessOptions harness;
  // What the estimator's odometry knows: the default models monocular VO (scale drifts ~1 % per
  // keyframe); a VIO is metric, its scale hardly drifts (scale_sigma 0.002; with 0.01 the graph
  // explains the VIO's local errors by scale changes: MH_05 58 % -> 73 %, docs/POSEGRAPH.md).
  OdometryWeighting odometry;
};

// Every `stride`-th associated pose becomes a keyframe. Leading raw poses equal to the identity
// are dropped: they are the estimator's output before it initialised (the EuRoC VIO files start
// with one or two), not keyframe poses a vSLAM would hand over (the first real pose is rotated
// by up to 105 degrees from them).
inline DriftCase LoadDriftCase(const std::string& name, const std::filesystem::path& raw_path,
                               const std::filesystem::path& gt_path, AssociationMethod method,
                               int stride) {
  Trajectory raw = ReadTrajectory(raw_path);
  size_t first = 0;
  while (first < raw.poses.size() && raw.poses[first].world_from_cam.translation.isZero(0.0) &&
         raw.poses[first].world_from_cam.rotation.vec().isZero(0.0)) {
    ++first;
  }
  raw.poses.erase(raw.poses.begin(), raw.poses.begin() + static_cast<std::ptrdiff_t>(first));
  const Trajectory gt = ReadTrajectory(gt_path);
  AssociationOptions ao;
  ao.method = method;
  ao.max_dt = 0.01;
  const Association assoc = Associate(raw, gt, ao);
  DriftCase c;
  c.name = name;
  for (size_t k = 0; k < assoc.pairs.size(); k += static_cast<size_t>(stride)) {
    c.raw.push_back(Sim3d(raw.poses[assoc.pairs[k].first].world_from_cam));
    c.gt.push_back(Sim3d(gt.poses[assoc.pairs[k].second].world_from_cam));
  }
  return c;
}

// The five real-drift cases (files under `data_dir`, the shared data folder), with the harness
// settings of each: keyframe spacing and the revisit distance are properties of the sequence
// (a car on streets vs a drone in a room), not of the pose graph.
inline std::vector<DriftCase> LoadDriftCases(const std::filesystem::path& data_dir) {
  const auto root = data_dir / "vslam_trajectories";
  std::vector<DriftCase> cases;
  DriftCase kitti = LoadDriftCase("kitti09", root / "kitti09_10/example_0/09.txt",
                                  data_dir / "kitti_gt_poses/09.txt", AssociationMethod::kIndex, 3);
  kitti.harness.distance = 8.0;
  kitti.harness.min_gap = 100;
  kitti.harness.query_stride = 1;
  kitti.harness.scale_min_extent = 10.0;
  cases.push_back(kitti);
  const std::pair<const char*, const char*> euroc[] = {{"MH_01", "MH_01_easy.txt"},
                                                       {"MH_03", "MH_03_medium.txt"},
                                                       {"MH_05", "MH_05_difficult.txt"},
                                                       {"V2_01", "V2_01_easy.txt"}};
  for (const auto& [seq, gt] : euroc) {
    DriftCase c =
        LoadDriftCase(std::string("euroc_") + seq, root / "euroc" / seq / "vio_mono_estimate.txt",
                      root / "euroc" / gt, AssociationMethod::kTimestamp, 5);
    c.harness.distance = 0.5;
    c.harness.min_gap = 60;
    c.harness.query_stride = 8;
    c.harness.scale_min_extent = 1.0;
    c.odometry.scale_sigma = 0.002;  // a VIO: metric
    cases.push_back(c);
  }
  return cases;
}

}  // namespace sparseloop::test
