#pragma once
// Pose graph over keyframe poses with odometry and loop edges, optimised with Ceres.
//
// Vertices are keyframe poses world_from_keyframe stored as Sim3d; the VertexType of the graph
// chooses the degrees of freedom (Sim(3) for monocular input, SE(3) for metric input, 4-DoF for
// gravity-aligned VIO, SE(2) for planar benchmark graphs). Edges measure a_from_b.
// Loops are kept apart from the other edges so that outlier rejection (PCM) can drop them; the
// summary reports which loops were rejected.
#include <array>
#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "sparseloop/core/loop_pair.h"
#include "sparseloop/core/sim3.h"
#include "sparseloop/posegraph/types.h"

namespace sparseloop {

// A non-loop edge (odometry, or any edge of a g2o file): measures from_from_to, i.e. the pose
// of vertex `to` in the frame of vertex `from`.
struct PoseGraphEdge {
  int64_t from = 0;
  int64_t to = 0;
  Sim3d from_from_to;  // measured relative pose
  // Information (inverse covariance) in tangent order [upsilon(3), omega(3), sigma]; units
  // 1/unit^2, 1/rad^2, 1/(log scale)^2.
  Matrix7d information = Matrix7d::Identity();
  // The information is the inverse of a covariance the caller knows for this step
  // (KeyframeInput::odometry_covariance). PCM's pairwise test then takes this step's variances
  // from it instead of its own per-step model (PcmOptions); only edges between consecutive
  // vertices (insertion order) are steps.
  bool information_from_caller = false;
};

// A loop closure as the detector measures it (the loop module converts its result into this).
struct LoopConstraint {
  int64_t query_id = 0;  // the later keyframe
  int64_t match_id = 0;  // the earlier keyframe it revisits
  // Pose of the query keyframe in the match keyframe's frame. With depths the detector solves the
  // full Sim(3); with 2D-only matches see MakeLoopConstraintFromDirection (scale 1, translation
  // magnitude taken from the raw trajectory).
  Sim3d match_from_query;
  // Information in tangent order [upsilon, omega, sigma]; multiplied by `weight`.
  Matrix7d information = Matrix7d::Identity();
  double weight = 1.0;    // unitless multiplier of the information (e.g. inlier ratio)
  bool has_scale = true;  // false: the relative scale is unknown; its information is zeroed
};

// Information of odometry edges built from consecutive raw vSLAM poses. A raw step of length L
// (raw units) gets standard deviations
//   translation: max(translation_fraction * L, min_translation_sigma)   (raw units, isotropic)
//   rotation:    rotation_sigma_rad                                       (rad, isotropic)
//   log scale:   scale_sigma                                              (unitless)
// i.e. information = diag(1/sigma^2). Uncertainty proportional to the distance travelled is the
// usual VO drift model. The defaults are what real monocular vSLAM / VIO keyframe steps show
// against their GT (docs/POSEGRAPH.md, "Odometry information"; DriftData.OdometryNoise): median
// per-step rotation error 0.05-0.3 deg, translation 2.5-7 % of the step; scale drift up to ~1 %
// per keyframe. A verified loop (its own, tighter covariance) then wins over the chain.
struct OdometryWeighting {
  double translation_fraction = 0.05;   // unitless: sigma_t / step length
  double min_translation_sigma = 1e-3;  // raw units: floor for stationary steps
  double rotation_sigma_rad = 0.003;    // rad per step
  double scale_sigma = 0.01;            // log-scale per step (only used by Sim(3) graphs)
  void Check() const;
  Matrix7d Information(const Sim3d& from_from_to) const;
  // The information of a step whose covariance the caller knows (KeyframeInput::
  // odometry_covariance): the inverse of the 6x6 covariance in tangent order [translation(3),
  // rotation(3)] (raw units^2, rad^2), and 1 / scale_sigma^2 for the log scale. Throws
  // std::invalid_argument unless the covariance is finite, symmetric (1e-9 relative) and positive
  // definite.
  Matrix7d InformationFromCovariance(const Eigen::Matrix<double, 6, 6>& covariance) const;
};

enum class RobustLoss { kTrivial, kHuber, kCauchy };
const char* ToString(RobustLoss loss);  // "trivial", "huber", "cauchy"
enum class OutlierRejection {
  kNone,  // plain least squares (with the chosen robust loss)
  kPcm,   // pairwise consistency maximisation, then the solve with accepted loops
};
const char* ToString(OutlierRejection rejection);  // "none", "pcm"

// Pairwise consistency maximisation (Mangelson et al. 2018, as in Kimera-RPGO). Two loops a, b
// are consistent when the cycle  Z_a * odom(q_a -> q_b) * Z_b^-1 * odom(m_b -> m_a)  is close to
// identity in the Mahalanobis sense; the largest set of mutually consistent loops (maximum clique)
// is kept. Odometry over the raw (initial) vertex poses; its covariance is accumulated with the
// per-step model below, including the lever arm of rotation and scale drift over the chain. A step
// whose edge carries the caller's covariance (PoseGraphEdge::information_from_caller) uses that
// instead: the largest eigenvalue of its translation block and of its rotation block (rotation
// also drives the lever arm); the log scale keeps the model's step_scale_sigma.
struct PcmOptions {
  double confidence = 0.99;                 // chi2 quantile used as the threshold (unitless)
  double step_translation_fraction = 0.05;  // sigma_t per step / step length (unitless)
  double step_rotation_sigma_rad = 0.01;    // rad per step (also the lever-arm drift rate)
  double step_scale_sigma = 0.01;           // log-scale per step (also lever arm); Sim(3) only
  size_t max_exact_clique = 64;             // loops; above this a greedy clique is used
  // A loop that leaves its relative scale free (se3_metric: PnP against the match's points)
  // carries scale 1 in its pose, wrong by the scale drift between match and query; the cycle of
  // two loops then misses by that error times the match chain's length. On: the cycle's
  // translation is tested with the free scale's prior (the chain's scale variance between the
  // loop's match and query) along that lever arm, instead of at scale 1. Off by default until the
  // drift family is re-run with it (docs/POSEGRAPH.md, "Loops with a free scale in PCM").
  bool free_scale_prior = false;
  // Besides the pairwise test, each loop against its own odometry chain (Kimera-RPGO's odometry
  // check): the loop's residual at the raw poses, translation and rotation (the scale
  // marginalised out: render and real scale drift has a bias the random-walk model does not
  // hold, docs/POSEGRAPH.md), with the loop's full information plus the chain model's covariance
  // between match and query. The model is calibrated by the loops themselves: every chi2 is
  // divided by max(1, the loops' median of chi2 / its median under the model), so a drift
  // beyond the per-step sigmas (the castle ring's 1 deg per keyframe) does not reject the true
  // loops, only loops far from what the others show; with one loop the test always passes. A
  // loop whose calibrated chi2 is above the `odometry_check_confidence` quantile is rejected even
  // when no other loop contradicts it: the pairwise test, which uses each loop's marginal
  // variances, calls a loop whose rotation is known only together with its translation (a
  // Sim(3) from two triangulated sides, no depths) consistent with every other, and a run of such
  // loops to the same wrong place was kept with the true ones (no depths, aerial circuit: 12
  // false loops). docs/POSEGRAPH.md, "Each loop against its odometry".
  bool odometry_check = true;
  double odometry_check_confidence = 0.99;  // chi2 quantile of the single-loop test
  // Sim(3) graphs: the pairwise test on the raw trajectory rescaled by its scale drift as the
  // loops measure it. Each loop with a measured scale s says log-scale(query) - log-scale(match)
  // = log s; a robust (Huber) least-squares profile over the vertices, a random walk of
  // step_scale_sigma per step between them, gives every raw step its scale, and the cycles of
  // two loops are composed on the rescaled raw poses with the loops in the same units. Without
  // it a long chain's raw translation carries the scale change along it (a render's or a real
  // monocular drift has a bias the random walk does not hold: 4x the renders' drift changes the
  // scale 6x over street00), and two true loops far apart in time miss each other by tens of
  // metres: PCM kept one group and rejected the other (docs/POSEGRAPH.md, "The scale profile").
  bool scale_profile = true;
  void Check() const;
};

struct PoseGraphOptions {
  int max_iterations = 100;  // Levenberg-Marquardt iterations
  // Relative cost change for convergence. 1e-5, not Ceres' 1e-6: on every graph measured the
  // extra iterations 1e-6 buys change the final cost by < 1e-4 relative and no ATE in the 4th
  // digit (DriftData, sphere2500), while a warm re-solve after one new loop needs 2 iterations
  // instead of 3 (bench_posegraph; 1e-4 would make it 1).
  double function_tolerance = 1e-5;
  double gradient_tolerance = 1e-10;  // Ceres gradient tolerance
  double parameter_tolerance = 1e-8;  // Ceres parameter tolerance
  // Levenberg-Marquardt's first trust region (Ceres' initial_trust_region_radius; 1/damping).
  // Large: the first steps are nearly Gauss-Newton. A drifted pose graph is close to linear in
  // the corrected poses, so full steps are accepted; with Ceres' default (1e4) the damping held
  // the steps back and the 5,000-keyframe benchmark needed 26 iterations instead of 5 to reach
  // the same cost (bench_posegraph). A rejected step still shrinks the region as usual.
  double initial_trust_region_radius = 1e8;
  // Loss on loop residuals. Trivial by default: at the first solve the drift makes true loops
  // look like huge residuals, and a redescending loss (Cauchy) would ignore exactly those.
  RobustLoss loop_loss = RobustLoss::kTrivial;
  RobustLoss edge_loss = RobustLoss::kTrivial;  // loss on non-loop edges
  double loss_scale = 1.0;  // whitened residual units (sigmas) where the robust loss bends
  OutlierRejection rejection = OutlierRejection::kPcm;
  PcmOptions pcm;
  int num_threads = 1;  // Ceres threads
  // Sim(3) graphs: solve without the vertices that only continue an odometry chain (two edges,
  // no loop, not the gauge), each chain between two kept vertices replaced by its composed edge
  // with the propagated covariance; the chain vertices are then recovered from the solved ends
  // (src/posegraph/chain_reduction.h). Exact marginalisation for a linear-Gaussian chain; on
  // Sim(3) the difference to the full solve is second order in the correction per chain. Every
  // `max_chain_length`-th chain vertex is kept (shorter chains: smaller linearisation error,
  // larger solve). Other vertex types always solve the full graph.
  bool reduce_chains = true;
  int max_chain_length = 8;   // edges per composed chain
  bool log_progress = false;  // per-iteration log through Logger() (never stdout)
  // When the kept loops as a whole are left inconsistent by the solve (LoopResidualCheck: chi2
  // above its quantile; "as a whole": the loop at `loop_weight_quantile` of chi2 / threshold is),
  // the odometry claimed more than it knows (its sigmas are a model, the loops' come from their
  // own inliers): the solve is repeated, warm, with every kept loop's information multiplied by
  // max(2, that quantile's chi2 / threshold) (at most max_loop_weight_scale in all), up to
  // loop_weight_rounds more times, until it is consistent. 0 rounds: off. The factor applies to
  // the solve only: PCM and the checks use the loops' own information. A minority of kept loops
  // left inconsistent is reported (the checks), not satisfied by weighting every loop up: with
  // the worst loop deciding (quantile 1, the former rule), a few kept loops metres off on the
  // street00 renders scaled all loops x80-470 and bent the trajectory around them (KITTI t_err
  // 1.10 % at drift x2 against 0.79 % with the median; docs/POSEGRAPH.md).
  int loop_weight_rounds = 4;
  double max_loop_weight_scale = 1e4;
  double loop_weight_quantile = 0.5;  // in (0, 1]: 0.5 the median kept loop, 1 the worst
  void Check() const;
};

enum class PoseGraphStatus {
  kConverged,      // a Ceres convergence criterion was met
  kMaxIterations,  // ran out of iterations; the estimate is still updated
  kInterrupted,    // stopped by the interrupt flag; the estimate holds the last accepted step
  kFailed,         // Ceres failed (numerical problem); the estimate is unchanged
  kNothingToDo,    // fewer than two vertices
};
const char* ToString(PoseGraphStatus status);

// After a solve: how well the solution satisfies one loop, measured against the loop's own
// covariance. chi2 = r^T (weight x information) r with r = log(Z^-1 * inv(T_match) * T_query),
// dof = rank of the information; `consistent` when chi2 <= the chi-square quantile at
// PcmOptions::confidence. A loop the graph cannot satisfy (true loop with too small a covariance,
// or a wrong loop PCM let through) shows here instead of silently bending the trajectory.
struct LoopResidualCheck {
  size_t loop = 0;  // index into PoseGraph::loops()
  int64_t query_id = 0;
  int64_t match_id = 0;
  double chi2 = 0.0;
  int dof = 0;
  double threshold = 0.0;  // chi-square quantile for dof
  bool consistent = true;
  double translation_error = 0.0;   // |upsilon| of r, match-camera units
  double rotation_error_rad = 0.0;  // |omega| of r
  double log_scale_error = 0.0;     // sigma of r
};

struct PoseGraphSummary {
  PoseGraphStatus status = PoseGraphStatus::kNothingToDo;
  // 0.5 * sum of squared (robustified) residuals over every edge and used loop of the graph (Ceres
  // convention; with reduce_chains evaluated on the full graph, not the reduced problem).
  double initial_cost = 0.0;
  double final_cost = 0.0;
  int iterations = 0;
  double solve_seconds = 0.0;      // Ceres time (+ chain reduction and recovery)
  double rejection_seconds = 0.0;  // PCM time
  size_t num_vertices = 0;
  size_t num_edges = 0;
  size_t num_loops = 0;
  size_t num_solved_vertices = 0;      // vertices in the Ceres problem (fewer with reduce_chains)
  std::vector<size_t> rejected_loops;  // indices into PoseGraph::loops()
  std::vector<LoopPair> rejected_loop_ids;  // {query_id, match_id} of each rejected loop
  // One per loop used in the solve (not rejected), in loops() order; see LoopResidualCheck.
  std::vector<LoopResidualCheck> loop_checks;
  // The factor the kept loops' information was multiplied by in the final solve
  // (PoseGraphOptions::loop_weight_rounds; 1 = their own information), and the solves it took.
  double loop_weight_scale = 1.0;
  int solves = 1;
  std::string ceres_message;
  std::string BriefReport() const;
};

class PoseGraph {
 public:
  explicit PoseGraph(VertexType type = VertexType::kSim3) : type_(type) {}

  VertexType vertex_type() const { return type_; }

  // Adds a vertex; its pose is also remembered as the raw (initial) pose that PCM uses.
  void AddVertex(int64_t id, const Sim3d& world_from_vertex);
  // Initial estimate and raw pose differ when a keyframe arrives after a correction: the estimate
  // is the corrected chain, the raw pose is what odometry said (PCM compares loops on raw poses).
  void AddVertex(int64_t id, const Sim3d& world_from_vertex, const Sim3d& raw_world_from_vertex);
  bool HasVertex(int64_t id) const { return index_.count(id) > 0; }
  const Sim3d& Pose(int64_t id) const;
  const Sim3d& RawPose(int64_t id) const;
  void SetPose(int64_t id, const Sim3d& world_from_vertex);
  // Vertex ids in insertion order (time order for a SLAM graph).
  const std::vector<int64_t>& VertexIds() const { return ids_; }
  size_t num_vertices() const { return ids_.size(); }

  void AddEdge(const PoseGraphEdge& edge);
  // Returns the index of the loop in loops().
  size_t AddLoop(const LoopConstraint& loop);
  const std::vector<PoseGraphEdge>& edges() const { return edges_; }
  const std::vector<LoopConstraint>& loops() const { return loops_; }

  // The gauge: Sim(3) has 7 gauge degrees of freedom (SE(3) 6, 4-DoF 4, SE(2) 3): the whole graph
  // can be moved, rotated (and scaled) without changing any residual, which leaves the normal
  // equations singular. Holding one vertex constant fixes it. Default: the first vertex added.
  void SetFixedVertex(int64_t id);
  int64_t fixed_vertex() const;

  // Synchronous, deterministic solve. `interrupt` (optional, non-owning) is polled after every
  // iteration; when it becomes true the solve stops with status kInterrupted.
  PoseGraphSummary Optimize(const PoseGraphOptions& options,
                            const std::atomic<bool>* interrupt = nullptr);

  // Indices of loops that PCM keeps (maximum clique of pairwise-consistent loops). Evaluates
  // every pair of loops.
  std::vector<size_t> PcmConsistentLoops(const PcmOptions& options) const;
  // The same result, with the pairwise tests of earlier calls kept (Optimize uses it): loops and
  // raw poses are append-only, so a pair's test never changes and only the pairs with a loop
  // added since the last call are evaluated (O(new loops x loops) instead of O(loops^2); at 2,000
  // loops the full test is ~2 million Sim(3) cycles). Recomputed from scratch when the test's
  // options change. Not thread-safe (a graph is solved by one thread at a time).
  std::vector<size_t> PcmConsistentLoopsIncremental(const PcmOptions& options);

  // The residual of loop `index` at the current estimates against its own covariance
  // (LoopResidualCheck); `confidence` as PcmOptions::confidence.
  LoopResidualCheck CheckLoop(size_t index, double confidence) const;

 private:
  // One solve of Optimize: the kept loops (use_loop) with their information x loop_scale; fills
  // the solve fields of *summary (costs, status, timings, rejected loops, loop checks).
  void SolveOnce(const PoseGraphOptions& options, const std::vector<bool>& use_loop,
                 double loop_scale, const std::atomic<bool>* interrupt, PoseGraphSummary* summary);
  // Steps of SolveOnce. The vertices chain reduction must keep (the fixed one, the ends of the
  // used loops).
  std::vector<bool> VerticesToKeep(const std::vector<bool>& use_loop) const;
  // After a solve: poses from the normalised parameters; each loop rejected (not used) or checked
  // against its covariance (CheckLoop).
  void AdoptSolution(const PoseGraphOptions& options, const std::vector<bool>& use_loop,
                     PoseGraphSummary* summary);
  size_t Index(int64_t id) const;
  // 0.5 * sum of (robustified) squared residuals of every edge and every used loop at the current
  // estimates (Sim(3) residuals; used when the solved problem is the reduced one).
  double FullCost(const PoseGraphOptions& options, const std::vector<bool>& use_loop) const;
  // Sets (*adj) to the pairwise consistency of all loops, computing only the pairs with a loop
  // index >= from (the rest of *adj must hold the earlier result).
  // Also sets odometry->chi2[k] / dof[k] for k >= from: loop k's single-loop odometry statistic
  // (PcmOptions::odometry_check; dof 0 when it is off).
  struct OdometryResiduals {
    std::vector<double> chi2;
    std::vector<int> dof;
  };
  // `variances`: each loop's marginal variances (PcmLoopVariances); `log_scale`:
  // PcmOptions::scale_profile's profile (one entry per vertex), or empty.
  void ExtendPcmAdjacency(const PcmOptions& options, size_t from,
                          const std::vector<Vector7d>& variances,
                          const std::vector<double>& log_scale, std::vector<std::vector<bool>>* adj,
                          OdometryResiduals* odometry) const;
  // Appends the marginal variances of loops_[variances->size()..] (loops are append-only).
  void PcmLoopVariances(std::vector<Vector7d>* variances) const;
  // PcmOptions::scale_profile: log of the factor that takes raw units at each vertex to raw units
  // at the first (0 there); empty when off or the graph is not Sim(3).
  std::vector<double> PcmScaleProfile(const PcmOptions& options,
                                      const std::vector<Vector7d>& variances) const;

  struct PcmCache {
    bool valid = false;
    PcmOptions options;
    size_t loops = 0;  // loops covered by adj
    std::vector<std::vector<bool>> adj;
    OdometryResiduals odometry;
    std::vector<double> log_scale;    // the profile the cached pairs were computed with
    std::vector<Vector7d> variances;  // each loop's marginal variances
  };
  PcmCache pcm_cache_;

  VertexType type_;
  std::vector<int64_t> ids_;
  std::unordered_map<int64_t, size_t> index_;
  std::vector<Vector8d> params_;  // current estimates, Sim3d::ToVector order
  std::vector<Sim3d> poses_;      // current estimates as Sim3d (kept in sync with params_)
  std::vector<Sim3d> raw_poses_;
  std::vector<PoseGraphEdge> edges_;
  std::vector<std::array<size_t, 2>> edge_ends_;  // vertex indices {from, to} of each edge
  std::vector<LoopConstraint> loops_;
  std::optional<int64_t> fixed_;
};

// Builds a graph whose vertices are the raw keyframe poses (ids[i] -> raw_world_from_keyframe[i],
// in time order) and whose edges are the consecutive raw relative poses weighted by `weighting`;
// where `step_covariance` (empty, or one entry per keyframe: the step ending there) holds the
// caller's covariance, by its inverse (OdometryWeighting::InformationFromCovariance, flagged
// PoseGraphEdge::information_from_caller). Throws std::invalid_argument naming the keyframe id
// for a covariance that is not positive definite.
PoseGraph BuildOdometryGraph(
    const std::vector<int64_t>& ids, const std::vector<Sim3d>& raw_world_from_keyframe,
    VertexType type, const OdometryWeighting& weighting = {},
    const std::vector<std::optional<Eigen::Matrix<double, 6, 6>>>& step_covariance = {});

// Loop constraint from a 2D-only relative pose (rotation + unit translation direction, as the
// essential matrix gives). The translation magnitude is unobservable from the two views; it is
// taken as `baseline_in_steps` times `local_step_length`, the raw distance between the query and
// its previous keyframe (the raw trajectory's local scale at the query). The magnitude gets a
// large uncertainty (magnitude_sigma_fraction of the magnitude along the direction), the
// perpendicular directions `direction_sigma_rad` times the magnitude, and the scale no
// information (has_scale = false).
struct DirectionLoopOptions {
  double baseline_in_steps = 1.0;         // unitless: assumed |t| / local step length
  double magnitude_sigma_fraction = 1.0;  // unitless: sigma along the direction / magnitude
  double direction_sigma_rad = 0.05;      // rad: angular uncertainty of the direction
  double rotation_sigma_rad = 0.01;       // rad
  double weight = 1.0;                    // unitless information multiplier
  void Check() const;
};
// The magnitude is converted from world units into the query's frame with the raw query scale
// (1 for raw vSLAM poses); the raw match pose is used only to check the ids' poses are valid.
LoopConstraint MakeLoopConstraintFromDirection(int64_t query_id, int64_t match_id,
                                               const Sim3d& raw_world_from_query,
                                               const Sim3d& raw_world_from_match,
                                               const Eigen::Quaterniond& match_from_query_rotation,
                                               const Eigen::Vector3d& unit_direction,
                                               double local_step_length,
                                               const DirectionLoopOptions& options = {});

// The information the solver uses for a loop: weight x information, the scale row and column
// zeroed when !has_scale.
Matrix7d LoopEffectiveInformation(const LoopConstraint& loop);

// Loop information from standard deviations (translation in the query's raw units, rotation in
// rad, log-scale unitless): diag(1/sigma^2).
Matrix7d LoopInformation(double translation_sigma, double rotation_sigma_rad, double scale_sigma);

}  // namespace sparseloop
