#pragma once
// Trajectory error metrics, reproducing the ecosystem's tools (see docs/METRICS.md):
//  - ATE  (evo_ape, translation part): e_i = | p_gt_i - T * p_est_i |, T = gt_from_est alignment.
//  - RPE  (evo_rpe, relative error E = inv(Q_i^-1 Q_j) * (P_i^-1 P_j), Q = gt, P = aligned est):
//         translation error |t(E)| (gt units), rotation error angle(R(E)) in degrees; pairs (i, j)
//         chosen on the gt poses exactly like evo's filters.id_pairs_from_delta (frames: ids
//         0, d, 2d, ... consecutive; meters: the path-accumulation rule of
//         filter_pairs_by_path, all_pairs false).
//  - KITTI odometry metric, exactly the devkit's evaluate_odometry.cpp: cumulative gt path
//         distances, segment lengths 100..800 m, first frames every 10 frames,
//         lastFrameFromSegmentLength (first frame whose distance exceeds dist[first] + len),
//         pose_error = inv(inv(P_f) P_l) * (inv(Q_f) Q_l), r_err = acos(clamp(0.5 (tr(R) - 1)))
//         / len, t_err = |t(pose_error)| / len, averaged over all segments; reported as
//         t_err * 100 (%) and r_err * 180/pi * 100 (deg/100 m), like the KITTI tables. The devkit
//         stores distances and errors in float; this implementation uses double throughout.
//
// Positions-only estimates (Trajectory::has_rotation false): every metric that would use the
// estimate's orientation uses the gt orientation at the same index instead. Then the
// translation part of inv(P_f^-1 P_l) (Q_f^-1 Q_l) has norm |(q_l - q_f) - (p_l - p_f)|, i.e. the
// error of the displacement vector (aligned est vs gt), which is what is reported; all rotation
// metrics are std::nullopt (not computable). The same applies when the gt has no rotation (then
// identity is used for both).
#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "sparseloop/core/rigid3.h"
#include "sparseloop/core/sim3.h"
#include "sparseloop/core/trajectory.h"
#include "sparseloop/eval/align.h"
#include "sparseloop/eval/associate.h"

namespace sparseloop {

// Summary statistics of a list of errors (numpy semantics: median averages the two middle values
// of an even count; std is the population standard deviation). All zero when count == 0.
struct ErrorStatistics {
  double rmse = 0.0;
  double mean = 0.0;
  double median = 0.0;
  double std = 0.0;
  double min = 0.0;
  double max = 0.0;
  size_t count = 0;
  std::vector<double> errors;  // per pair, in input order
};
ErrorStatistics ComputeStatistics(std::vector<double> errors);

// Absolute trajectory error of positions (metres or gt units).
using AteResult = ErrorStatistics;

// gt[i] corresponds to est[i]; each est point is mapped by gt_from_est before the difference.
// Throws std::invalid_argument when the sizes differ.
AteResult ComputeAte(const std::vector<Eigen::Vector3d>& gt,
                     const std::vector<Eigen::Vector3d>& est, const Sim3d& gt_from_est = {});

// world_from_cam of an estimate pose expressed in the gt world: rotation R_a R_p, translation
// s R_a t_p + t_a (evo's align/scale of a trajectory). The camera frame itself is not scaled.
Rigid3d ApplyAlignment(const Sim3d& gt_from_est, const Rigid3d& est_world_from_cam);

enum class RpeUnit { kFrames, kMeters };
std::string ToString(RpeUnit unit);

// Largest RPE delta in frames (no trajectory is longer; a larger delta gives no pair anyway).
inline constexpr double kMaxRpeDeltaFrames = 1e9;

struct RpeOptions {
  // Frames (integer in [1, kMaxRpeDeltaFrames]) or metres (> 0) between pair members.
  double delta = 1.0;
  RpeUnit unit = RpeUnit::kFrames;  // unit of delta
  bool all_pairs = false;           // kFrames only: every (i, i + delta) instead of consecutive ids
  void Check() const;
};

// The evo pair selection on the gt poses (see header comment). Indices into `gt`.
std::vector<std::pair<size_t, size_t>> RpePairs(const std::vector<Rigid3d>& gt,
                                                const RpeOptions& options);

struct RpeResult {
  ErrorStatistics translation;                   // |t(E)|, gt units
  std::optional<ErrorStatistics> rotation_deg;   // angle(R(E)) in degrees; nullopt without rotation
  std::vector<std::pair<size_t, size_t>> pairs;  // (i, j) indices used
};

// gt[i] corresponds to est[i] (est already aligned, e.g. with ApplyAlignment). When
// `use_est_rotation` is false the estimate's orientation is replaced by the gt's (positions-only
// estimates) and rotation_deg is nullopt. Throws std::invalid_argument when sizes differ.
RpeResult ComputeRpe(const std::vector<Rigid3d>& gt, const std::vector<Rigid3d>& est,
                     const RpeOptions& options = {}, bool use_est_rotation = true);

struct KittiOptions {
  std::vector<double> lengths = {100, 200, 300, 400, 500, 600, 700, 800};  // metres, each > 0
  int step_size = 10;           // frames between segment start frames (devkit: 10 = 1 s), >= 1
  double frame_rate_hz = 10.0;  // only for KittiSegmentError::speed (devkit assumes 10 Hz), > 0
  void Check() const;
};

struct KittiSegmentError {
  size_t first_frame = 0;       // index into the (associated) pose lists
  size_t last_frame = 0;        // lastFrameFromSegmentLength
  double length = 0.0;          // nominal segment length, metres
  double t_err = 0.0;           // |t(pose_error)| / length, metres per metre
  std::optional<double> r_err;  // rotationError(pose_error) / length, rad per metre
  double speed = 0.0;           // length / (num_frames / frame_rate_hz), m/s (devkit formula)
};

struct KittiLengthError {
  double length = 0.0;                       // metres
  size_t count = 0;                          // segments of this length
  double t_err_pct = 0.0;                    // mean t_err * 100
  std::optional<double> r_err_deg_per_100m;  // mean r_err * 180/pi * 100
};

enum class KittiStatus { kOk, kNoSegments };

struct KittiResult {
  KittiStatus status = KittiStatus::kNoSegments;
  size_t num_segments = 0;
  std::optional<double> t_err_pct;           // mean t_err over all segments * 100
  std::optional<double> r_err_deg_per_100m;  // mean r_err over all segments * 180/pi * 100
  std::vector<KittiSegmentError> segments;   // devkit order: first frame, then length
  std::vector<KittiLengthError> per_length;  // one per option length with count > 0
};

// gt[i] corresponds to est[i]. `use_est_rotation` as in ComputeRpe.
// Throws std::invalid_argument when sizes differ.
KittiResult ComputeKittiMetric(const std::vector<Rigid3d>& gt, const std::vector<Rigid3d>& est,
                               const KittiOptions& options = {}, bool use_est_rotation = true);

struct EvaluationOptions {
  AssociationOptions association;          // how est poses are paired with gt poses
  Alignment alignment = Alignment::kSim3;  // applied to est before every metric (monocular: sim3)
  bool compute_rpe = true;
  RpeOptions rpe;
  bool compute_kitti = true;
  KittiOptions kitti;
  void Check() const;
};

enum class EvaluationStatus {
  kOk,
  kNoAssociation,  // no est pose could be paired with gt: every metric empty
};
std::string ToString(EvaluationStatus status);

struct TrajectoryEvaluation {
  EvaluationStatus status = EvaluationStatus::kNoAssociation;
  size_t num_est_poses = 0;
  size_t num_gt_poses = 0;
  Association association;
  bool rotation_evaluated = false;  // both trajectories carry orientation
  AlignmentResult alignment;
  AteResult ate;
  std::optional<RpeResult> rpe;      // nullopt when disabled
  std::optional<KittiResult> kitti;  // nullopt when disabled
};

// Association + Umeyama alignment on the associated positions + ATE, RPE, KITTI.
TrajectoryEvaluation EvaluateTrajectory(const Trajectory& gt, const Trajectory& est,
                                        const EvaluationOptions& options = {});

}  // namespace sparseloop
