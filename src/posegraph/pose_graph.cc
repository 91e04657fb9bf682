#include "sparseloop/posegraph/pose_graph.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <numeric>

#include <ceres/ceres.h>
#include <fmt/format.h>

#include "chain_reduction.h"
#include "edge_error.h"
#include "manifolds.h"
#include "sparseloop/core/check.h"
#include "sparseloop/core/covariance.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/core/timer.h"

namespace sparseloop {

const char* ToString(RobustLoss l) {
  switch (l) {
    case RobustLoss::kTrivial:
      return "trivial";
    case RobustLoss::kHuber:
      return "huber";
    case RobustLoss::kCauchy:
      return "cauchy";
  }
  return "?";
}
const char* ToString(OutlierRejection r) {
  switch (r) {
    case OutlierRejection::kNone:
      return "none";
    case OutlierRejection::kPcm:
      return "pcm";
  }
  return "?";
}
const char* ToString(VertexType v) {
  switch (v) {
    case VertexType::kSim3:
      return "sim3";
    case VertexType::kSe3:
      return "se3";
    case VertexType::kFourDof:
      return "4dof";
    case VertexType::kSe2:
      return "se2";
  }
  return "?";
}

int TangentSize(VertexType type) {
  switch (type) {
    case VertexType::kSim3:
      return 7;
    case VertexType::kSe3:
      return 6;
    case VertexType::kFourDof:
      return 4;
    case VertexType::kSe2:
      return 3;
  }
  return 7;
}

namespace {

// Row-major 8 x n PlusJacobian; `columns` is n. Quaternion rows for a rotation increment about
// the body axes (tangent columns 3..5): (q * [v, 1]) / 2 differentiated in v.
void SetBodyRotationRows(const double* x, int columns, double* j) {
  const double qx = x[0], qy = x[1], qz = x[2], qw = x[3];
  // m = [qw I + [qv]x ; -qv^T] / 2, rows x y z w.
  const double m[4][3] = {{qw, -qz, qy}, {qz, qw, -qx}, {-qy, qx, qw}, {-qx, -qy, -qz}};
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 3; ++c) j[r * columns + 3 + c] = 0.5 * m[r][c];
  }
}

void SetScaledRotationRows(const double* x, int columns, double* j) {
  const Eigen::Matrix3d r = x[7] * Eigen::Quaterniond(x[3], x[0], x[1], x[2]).toRotationMatrix();
  for (int row = 0; row < 3; ++row) {
    for (int c = 0; c < 3; ++c) j[(4 + row) * columns + c] = r(row, c);
  }
}

// Yaw about world z: d(Rz(y) q)/dy at 0 = (e_z * q) / 2; translation increments in world axes.
void YawPlusJacobian(const double* x, int translation_dims, double* j) {
  const int columns = translation_dims + 1;
  std::fill(j, j + 8 * columns, 0.0);
  const double qx = x[0], qy = x[1], qz = x[2], qw = x[3];
  j[0 * columns + translation_dims] = -0.5 * qy;
  j[1 * columns + translation_dims] = 0.5 * qx;
  j[2 * columns + translation_dims] = 0.5 * qw;
  j[3 * columns + translation_dims] = -0.5 * qz;
  for (int i = 0; i < translation_dims; ++i) j[(4 + i) * columns + i] = 1.0;
}

}  // namespace

void Sim3PlusJacobian(const double* x, double* jacobian) {
  std::fill(jacobian, jacobian + 8 * 7, 0.0);
  SetBodyRotationRows(x, 7, jacobian);
  SetScaledRotationRows(x, 7, jacobian);
  jacobian[7 * 7 + 6] = x[7];
}

void Se3OnSim3PlusJacobian(const double* x, double* jacobian) {
  std::fill(jacobian, jacobian + 8 * 6, 0.0);
  SetBodyRotationRows(x, 6, jacobian);
  SetScaledRotationRows(x, 6, jacobian);
}

void FourDofPlusJacobian(const double* x, double* jacobian) { YawPlusJacobian(x, 3, jacobian); }
void Se2OnSim3PlusJacobian(const double* x, double* jacobian) { YawPlusJacobian(x, 2, jacobian); }

std::unique_ptr<ceres::Manifold> CreateVertexManifold(VertexType type) {
  switch (type) {
    case VertexType::kSim3:
      return std::make_unique<Sim3Manifold>();
    case VertexType::kSe3:
      return std::make_unique<Se3OnSim3Manifold>();
    case VertexType::kFourDof:
      return std::make_unique<FourDofManifold>();
    case VertexType::kSe2:
      return std::make_unique<Se2OnSim3Manifold>();
  }
  return std::make_unique<Sim3Manifold>();
}

Matrix7d SqrtInformation(const Matrix7d& information) {
  SL_CHECK_MSG(information.allFinite(), "information matrix has NaN or Inf");
  SL_CHECK_MSG((information - information.transpose()).cwiseAbs().maxCoeff() <=
                   1e-9 * std::max(1.0, information.cwiseAbs().maxCoeff()),
               "information matrix is not symmetric");
  // Diagonal (every odometry edge, OdometryWeighting): the square root is elementwise. This is
  // also what skips a 7x7 eigen-decomposition per edge at every solve.
  const Matrix7d off_diagonal = information - Matrix7d(information.diagonal().asDiagonal());
  if (off_diagonal.isZero(0.0)) {
    const Eigen::Matrix<double, 7, 1> d = information.diagonal();
    const double tol = 1e-9 * std::max(1.0, d.cwiseAbs().maxCoeff());
    SL_CHECK_MSG(d.minCoeff() >= -tol, "information matrix is not positive semi-definite");
    return Matrix7d(d.cwiseMax(0.0).cwiseSqrt().asDiagonal());
  }
  Eigen::SelfAdjointEigenSolver<Matrix7d> eig(information);
  const Eigen::Matrix<double, 7, 1> values = eig.eigenvalues();
  const double tol = 1e-9 * std::max(1.0, values.cwiseAbs().maxCoeff());
  SL_CHECK_MSG(values.minCoeff() >= -tol, "information matrix is not positive semi-definite");
  const Eigen::Matrix<double, 7, 1> sqrt_values = values.cwiseMax(0.0).cwiseSqrt();
  return sqrt_values.asDiagonal() * eig.eigenvectors().transpose();
}

void OdometryWeighting::Check() const {
  SL_CHECK_MSG(translation_fraction > 0, "translation_fraction must be > 0, got {}",
               translation_fraction);
  SL_CHECK_MSG(min_translation_sigma > 0, "min_translation_sigma must be > 0, got {}",
               min_translation_sigma);
  SL_CHECK_MSG(rotation_sigma_rad > 0, "rotation_sigma_rad must be > 0, got {}",
               rotation_sigma_rad);
  SL_CHECK_MSG(scale_sigma > 0, "scale_sigma must be > 0, got {}", scale_sigma);
}

Matrix7d OdometryWeighting::Information(const Sim3d& from_from_to) const {
  const double length = from_from_to.translation.norm();
  const double sigma_t = std::max(translation_fraction * length, min_translation_sigma);
  return LoopInformation(sigma_t, rotation_sigma_rad, scale_sigma);
}

Matrix7d OdometryWeighting::InformationFromCovariance(
    const Eigen::Matrix<double, 6, 6>& covariance) const {
  SL_CHECK_MSG(covariance.allFinite(), "odometry covariance must be finite");
  const double asym = (covariance - covariance.transpose()).cwiseAbs().maxCoeff();
  SL_CHECK_MSG(asym <= 1e-9 * std::max(1e-300, covariance.cwiseAbs().maxCoeff()),
               "odometry covariance must be symmetric (largest |C - C^T| {})", asym);
  const Eigen::LLT<Eigen::Matrix<double, 6, 6>> llt(covariance);
  SL_CHECK_MSG(llt.info() == Eigen::Success && covariance.diagonal().minCoeff() > 0,
               "odometry covariance must be positive definite (smallest diagonal element {})",
               covariance.diagonal().minCoeff());
  // A usable inverse too: tiny variances (1e-30) gave an information the chain reduction's
  // Cholesky could not factor, in the optimizer thread.
  const auto problem = CheckCovariance(covariance);
  SL_CHECK_MSG(!problem, "odometry covariance: {}", problem ? problem->Message() : "");
  Matrix7d information = Matrix7d::Zero();
  information.topLeftCorner<6, 6>() = llt.solve(Eigen::Matrix<double, 6, 6>::Identity());
  information.topLeftCorner<6, 6>() =
      0.5 * (information.topLeftCorner<6, 6>() + information.topLeftCorner<6, 6>().transpose());
  information(6, 6) = 1.0 / (scale_sigma * scale_sigma);
  return information;
}

Matrix7d LoopInformation(double translation_sigma, double rotation_sigma_rad, double scale_sigma) {
  SL_CHECK_MSG(translation_sigma > 0 && rotation_sigma_rad > 0 && scale_sigma > 0,
               "sigmas must be > 0, got {} {} {}", translation_sigma, rotation_sigma_rad,
               scale_sigma);
  Eigen::Matrix<double, 7, 1> d;
  const double it = 1.0 / (translation_sigma * translation_sigma);
  const double ir = 1.0 / (rotation_sigma_rad * rotation_sigma_rad);
  d << it, it, it, ir, ir, ir, 1.0 / (scale_sigma * scale_sigma);
  return d.asDiagonal();
}

void PcmOptions::Check() const {
  SL_CHECK_MSG(confidence > 0 && confidence < 1, "pcm confidence must be in (0,1), got {}",
               confidence);
  SL_CHECK_MSG(step_translation_fraction > 0 && step_rotation_sigma_rad > 0 && step_scale_sigma > 0,
               "pcm step sigmas must be > 0");
  SL_CHECK_MSG(odometry_check_confidence > 0 && odometry_check_confidence < 1,
               "pcm odometry_check_confidence must be in (0,1), got {}", odometry_check_confidence);
}

void PoseGraphOptions::Check() const {
  SL_CHECK_MSG(max_iterations > 0, "max_iterations must be > 0, got {}", max_iterations);
  SL_CHECK_MSG(function_tolerance > 0, "function_tolerance must be > 0");
  SL_CHECK_MSG(gradient_tolerance > 0, "gradient_tolerance must be > 0");
  SL_CHECK_MSG(parameter_tolerance > 0, "parameter_tolerance must be > 0");
  // Bounded: Ceres squares it (1e-160 -> 0), and the Cauchy loss then gave a NaN cost reported as
  // converged.
  SL_CHECK_MSG(loss_scale >= 1e-6 && loss_scale <= 1e6,
               "loss_scale must be in [1e-6, 1e6] sigmas, got {}", loss_scale);
  SL_CHECK_MSG(initial_trust_region_radius > 0, "initial_trust_region_radius must be > 0, got {}",
               initial_trust_region_radius);
  SL_CHECK_MSG(num_threads >= 1, "num_threads must be >= 1, got {}", num_threads);
  SL_CHECK_MSG(max_chain_length >= 1, "max_chain_length must be >= 1, got {}", max_chain_length);
  SL_CHECK_MSG(loop_weight_rounds >= 0, "loop_weight_rounds must be >= 0, got {}",
               loop_weight_rounds);
  SL_CHECK_MSG(max_loop_weight_scale >= 1, "max_loop_weight_scale must be >= 1, got {}",
               max_loop_weight_scale);
  SL_CHECK_MSG(loop_weight_quantile > 0 && loop_weight_quantile <= 1,
               "loop_weight_quantile must be in (0, 1], got {}", loop_weight_quantile);
  pcm.Check();
}

void DirectionLoopOptions::Check() const {
  SL_CHECK_MSG(baseline_in_steps > 0, "baseline_in_steps must be > 0");
  SL_CHECK_MSG(magnitude_sigma_fraction > 0, "magnitude_sigma_fraction must be > 0");
  SL_CHECK_MSG(direction_sigma_rad > 0, "direction_sigma_rad must be > 0");
  SL_CHECK_MSG(rotation_sigma_rad > 0, "rotation_sigma_rad must be > 0");
  SL_CHECK_MSG(weight > 0, "weight must be > 0");
}

const char* ToString(PoseGraphStatus status) {
  switch (status) {
    case PoseGraphStatus::kConverged:
      return "converged";
    case PoseGraphStatus::kMaxIterations:
      return "max_iterations";
    case PoseGraphStatus::kInterrupted:
      return "interrupted";
    case PoseGraphStatus::kFailed:
      return "failed";
    case PoseGraphStatus::kNothingToDo:
      return "nothing_to_do";
  }
  return "unknown";
}

std::string PoseGraphSummary::BriefReport() const {
  return fmt::format(
      "Pose graph: {} vertices ({} in the solve), {} edges, {} loops ({} rejected); initial cost "
      "{:.6e}, final cost {:.6e}, {} iterations, {:.3f} s solve + {:.3f} s rejection, "
      "termination: {} ({})",
      num_vertices, num_solved_vertices, num_edges, num_loops, rejected_loops.size(), initial_cost,
      final_cost, iterations, solve_seconds, rejection_seconds, ToString(status), ceres_message);
}

void PoseGraph::AddVertex(int64_t id, const Sim3d& world_from_vertex) {
  AddVertex(id, world_from_vertex, world_from_vertex);
}

void PoseGraph::AddVertex(int64_t id, const Sim3d& world_from_vertex,
                          const Sim3d& raw_world_from_vertex) {
  SL_CHECK_MSG(!HasVertex(id), "duplicate vertex id {}", id);
  index_[id] = ids_.size();
  ids_.push_back(id);
  params_.push_back(world_from_vertex.ToVector());
  poses_.push_back(world_from_vertex);
  raw_poses_.push_back(raw_world_from_vertex);
}

size_t PoseGraph::Index(int64_t id) const {
  const auto it = index_.find(id);
  SL_CHECK_MSG(it != index_.end(), "unknown vertex id {}", id);
  return it->second;
}

const Sim3d& PoseGraph::Pose(int64_t id) const { return poses_[Index(id)]; }
const Sim3d& PoseGraph::RawPose(int64_t id) const { return raw_poses_[Index(id)]; }

void PoseGraph::SetPose(int64_t id, const Sim3d& world_from_vertex) {
  const size_t i = Index(id);
  poses_[i] = world_from_vertex;
  params_[i] = world_from_vertex.ToVector();
}

void PoseGraph::AddEdge(const PoseGraphEdge& edge) {
  Index(edge.from);
  Index(edge.to);
  SL_CHECK_MSG(edge.from != edge.to, "edge from a vertex to itself ({})", edge.from);
  SqrtInformation(edge.information);  // validates
  edges_.push_back(edge);
  edge_ends_.push_back({Index(edge.from), Index(edge.to)});
}

size_t PoseGraph::AddLoop(const LoopConstraint& loop) {
  Index(loop.query_id);
  Index(loop.match_id);
  SL_CHECK_MSG(loop.query_id != loop.match_id, "loop from a vertex to itself ({})", loop.query_id);
  SL_CHECK_MSG(loop.weight > 0 && std::isfinite(loop.weight), "loop weight must be > 0, got {}",
               loop.weight);
  SqrtInformation(loop.information);
  loops_.push_back(loop);
  return loops_.size() - 1;
}

void PoseGraph::SetFixedVertex(int64_t id) {
  Index(id);
  fixed_ = id;
}

int64_t PoseGraph::fixed_vertex() const {
  SL_CHECK_MSG(!ids_.empty(), "graph has no vertices");
  return fixed_ ? *fixed_ : ids_.front();
}

namespace {

ceres::LossFunction* MakeLoss(RobustLoss loss, double scale) {
  switch (loss) {
    case RobustLoss::kTrivial:
      return nullptr;
    case RobustLoss::kHuber:
      return new ceres::HuberLoss(scale);
    case RobustLoss::kCauchy:
      return new ceres::CauchyLoss(scale);
  }
  return nullptr;
}

class InterruptCallback : public ceres::IterationCallback {
 public:
  explicit InterruptCallback(const std::atomic<bool>* flag) : flag_(flag) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    if (flag_ != nullptr && flag_->load(std::memory_order_acquire)) {
      interrupted_ = true;
      // Keep the last accepted step: it is a better warm start than the previous solution.
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    }
    return ceres::SOLVER_CONTINUE;
  }
  bool interrupted() const { return interrupted_; }

 private:
  const std::atomic<bool>* flag_;
  bool interrupted_ = false;
};

class LogCallback : public ceres::IterationCallback {
 public:
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    Logger().info("posegraph iter {:3d} cost {:.6e} |step| {:.3e} tr_radius {:.3e}", s.iteration,
                  s.cost, s.step_norm, s.trust_region_radius);
    return ceres::SOLVER_CONTINUE;
  }
};

}  // namespace

double PoseGraph::FullCost(const PoseGraphOptions& options,
                           const std::vector<bool>& use_loop) const {
  const std::unique_ptr<ceres::LossFunction> edge_loss(
      MakeLoss(options.edge_loss, options.loss_scale));
  const std::unique_ptr<ceres::LossFunction> loop_loss(
      MakeLoss(options.loop_loss, options.loss_scale));
  const auto term = [](const ceres::LossFunction* loss, double squared) {
    if (loss == nullptr) return 0.5 * squared;
    double rho[3];
    loss->Evaluate(squared, rho);
    return 0.5 * rho[0];
  };
  // e^T Info e with e = log(Z^-1 inv(T_a) T_b): the squared norm of the whitened residual
  // (Sim3EdgeCost's), without forming the square root of the information.
  const auto squared_error = [this](const Sim3d& a_from_b, const Matrix7d& information, size_t a,
                                    size_t b) {
    const jet::Sim3<double> z = ToJetSim3(a_from_b);
    const jet::Sim3<double> ta = jet::Sim3<double>::FromArray(params_[a].data());
    const jet::Sim3<double> tb = jet::Sim3<double>::FromArray(params_[b].data());
    const jet::Vector7<double> e = (z.Inverse() * (ta.Inverse() * tb)).Log();
    return e.dot(information * e);
  };
  double cost = 0.0;
  for (size_t k = 0; k < edges_.size(); ++k) {
    const PoseGraphEdge& e = edges_[k];
    cost += term(edge_loss.get(),
                 squared_error(e.from_from_to, e.information, edge_ends_[k][0], edge_ends_[k][1]));
  }
  for (size_t k = 0; k < loops_.size(); ++k) {
    if (!use_loop[k]) continue;
    const LoopConstraint& loop = loops_[k];
    cost +=
        term(loop_loss.get(), squared_error(loop.match_from_query, LoopEffectiveInformation(loop),
                                            Index(loop.match_id), Index(loop.query_id)));
  }
  return cost;
}

namespace {

// The `quantile` of chi2 / threshold over the checked loops (nearest rank; 1 = the worst); 0 when
// no loop was checked.
double LoopCheckQuantile(const std::vector<LoopResidualCheck>& checks, double quantile) {
  std::vector<double> ratios;
  for (const LoopResidualCheck& c : checks)
    if (c.threshold > 0) ratios.push_back(c.chi2 / c.threshold);
  if (ratios.empty()) return 0.0;
  const auto rank = static_cast<size_t>(std::ceil(quantile * static_cast<double>(ratios.size())));
  const size_t k = std::clamp<size_t>(rank, 1, ratios.size()) - 1;
  std::nth_element(ratios.begin(), ratios.begin() + static_cast<std::ptrdiff_t>(k), ratios.end());
  return ratios[k];
}

}  // namespace

PoseGraphSummary PoseGraph::Optimize(const PoseGraphOptions& options,
                                     const std::atomic<bool>* interrupt) {
  options.Check();
  PoseGraphSummary summary;
  summary.num_vertices = ids_.size();
  summary.num_edges = edges_.size();
  summary.num_loops = loops_.size();
  if (ids_.size() < 2) {
    summary.status = PoseGraphStatus::kNothingToDo;
    summary.ceres_message = "fewer than two vertices";
    return summary;
  }

  // 1. Outlier rejection before the solve (PCM).
  std::vector<bool> use_loop(loops_.size(), true);
  if (options.rejection == OutlierRejection::kPcm) {
    Timer timer;
    std::fill(use_loop.begin(), use_loop.end(), false);
    for (size_t i : PcmConsistentLoopsIncremental(options.pcm)) use_loop[i] = true;
    summary.rejection_seconds = timer.ElapsedMs() / 1000.0;
  }

  // 2.-3. Solve; repeated with heavier loops while a kept loop stays inconsistent (see
  //        PoseGraphOptions::loop_weight_rounds).
  double loop_scale = 1.0;
  SolveOnce(options, use_loop, loop_scale, interrupt, &summary);
  for (int round = 0; round < options.loop_weight_rounds; ++round) {
    if (summary.status == PoseGraphStatus::kFailed ||
        summary.status == PoseGraphStatus::kInterrupted)
      break;
    const double excess = LoopCheckQuantile(summary.loop_checks, options.loop_weight_quantile);
    if (excess <= 1.0 || loop_scale >= options.max_loop_weight_scale) break;
    loop_scale = std::min(options.max_loop_weight_scale, loop_scale * std::max(2.0, excess));
    PoseGraphSummary again;
    again.num_vertices = summary.num_vertices;
    again.num_edges = summary.num_edges;
    again.num_loops = summary.num_loops;
    again.rejection_seconds = summary.rejection_seconds;
    SolveOnce(options, use_loop, loop_scale, interrupt, &again);
    again.initial_cost = summary.initial_cost;
    again.iterations += summary.iterations;
    again.solve_seconds += summary.solve_seconds;
    again.solves = summary.solves + 1;
    again.loop_weight_scale = loop_scale;
    summary = std::move(again);
  }
  if (summary.loop_weight_scale > 1.0)
    Logger().info(
        "pose graph: kept loops weighted x{:.3g} ({} solves) so that the graph satisfies "
        "them; the odometry model was tighter than the drift",
        summary.loop_weight_scale, summary.solves);
  return summary;
}

namespace {

ceres::Solver::Options SolverOptions(const PoseGraphOptions& options) {
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.initial_trust_region_radius = options.initial_trust_region_radius;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.gradient_tolerance = options.gradient_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  solver_options.num_threads = options.num_threads;
  solver_options.logging_type = ceres::SILENT;
  solver_options.minimizer_progress_to_stdout = false;
  return solver_options;
}

PoseGraphStatus StatusOf(const ceres::Solver::Summary& summary, bool interrupted) {
  if (interrupted) return PoseGraphStatus::kInterrupted;
  if (summary.termination_type == ceres::CONVERGENCE) return PoseGraphStatus::kConverged;
  if (summary.termination_type == ceres::NO_CONVERGENCE) return PoseGraphStatus::kMaxIterations;
  return PoseGraphStatus::kFailed;
}

// The used loops' residuals, each with its information x loop_scale.
template <typename ParamOf, typename MakeEdge>
void AddLoopResiduals(const std::vector<LoopConstraint>& loops, const std::vector<bool>& use_loop,
                      double loop_scale, const PoseGraphOptions& options, ParamOf param_of,
                      MakeEdge make_edge, ceres::Problem* problem) {
  for (size_t k = 0; k < loops.size(); ++k) {
    if (!use_loop[k]) continue;
    const LoopConstraint& loop = loops[k];
    const Matrix7d sqrt_info =
        std::sqrt(loop_scale) * SqrtInformation(LoopEffectiveInformation(loop));
    double* match = param_of(loop.match_id);
    double* query = param_of(loop.query_id);
    problem->AddResidualBlock(make_edge(loop.match_from_query, sqrt_info),
                              MakeLoss(options.loop_loss, options.loss_scale), match, query);
  }
}

}  // namespace

std::vector<bool> PoseGraph::VerticesToKeep(const std::vector<bool>& use_loop) const {
  std::vector<bool> must_keep(ids_.size(), false);
  must_keep[Index(fixed_vertex())] = true;
  for (size_t k = 0; k < loops_.size(); ++k) {
    if (!use_loop[k]) continue;
    must_keep[Index(loops_[k].query_id)] = true;
    must_keep[Index(loops_[k].match_id)] = true;
  }
  return must_keep;
}

void PoseGraph::AdoptSolution(const PoseGraphOptions& options, const std::vector<bool>& use_loop,
                              PoseGraphSummary* summary) {
  for (size_t i = 0; i < params_.size(); ++i) {
    Vector8d& p = params_[i];
    p.head<4>().normalize();
    poses_[i] = Sim3d::FromVector(p);
  }
  for (size_t k = 0; k < loops_.size(); ++k) {
    if (!use_loop[k]) {
      summary->rejected_loops.push_back(k);
      summary->rejected_loop_ids.push_back({loops_[k].query_id, loops_[k].match_id});
    } else {
      summary->loop_checks.push_back(CheckLoop(k, options.pcm.confidence));
    }
  }
}

void PoseGraph::SolveOnce(const PoseGraphOptions& options, const std::vector<bool>& use_loop,
                          double loop_scale, const std::atomic<bool>* interrupt,
                          PoseGraphSummary* out) {
  PoseGraphSummary& summary = *out;
  // The Ceres problem over the stored parameter blocks (only the kept ones when chains are
  //    reduced; see chain_reduction.h).
  Timer reduction_timer;
  const bool reduce = options.reduce_chains && type_ == VertexType::kSim3;
  internal::ChainReduction reduction;
  if (reduce) {
    reduction = internal::ReduceChains(edges_, edge_ends_, VerticesToKeep(use_loop),
                                       options.max_chain_length);
  }
  double reduction_seconds = reduction_timer.ElapsedMs() / 1000.0;

  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  const std::unique_ptr<ceres::Manifold> manifold = CreateVertexManifold(type_);
  for (size_t i = 0; i < ids_.size(); ++i) {
    if (reduce && !reduction.kept[i]) continue;
    problem.AddParameterBlock(params_[i].data(), 8, manifold.get());
  }
  summary.num_solved_vertices = reduce ? reduction.num_kept : ids_.size();
  // Sim(3) vertices: analytic Jacobians (Sim3EdgeCost, ~3x cheaper); the other vertex types
  // keep the autodiff residual (the analytic one is written for the Sim(3) manifold only).
  const auto make_edge = [this](const Sim3d& a_from_b, const Matrix7d& sqrt_information) {
    return type_ == VertexType::kSim3 ? Sim3EdgeCost::Create(a_from_b, sqrt_information)
                                      : EdgeError::Create(a_from_b, sqrt_information);
  };
  const auto add_edge = [&](const PoseGraphEdge& e) {
    problem.AddResidualBlock(make_edge(e.from_from_to, SqrtInformation(e.information)),
                             MakeLoss(options.edge_loss, options.loss_scale),
                             params_[Index(e.from)].data(), params_[Index(e.to)].data());
  };
  if (reduce) {
    for (const size_t e : reduction.direct_edges) add_edge(edges_[e]);
    for (const internal::ReducedChain& chain : reduction.chains) {
      problem.AddResidualBlock(
          Sim3EdgeCost::Create(FromJetSim3(chain.from_from_to), chain.sqrt_information),
          MakeLoss(options.edge_loss, options.loss_scale), params_[chain.from].data(),
          params_[chain.to].data());
    }
  } else {
    for (const PoseGraphEdge& e : edges_) add_edge(e);
  }
  AddLoopResiduals(
      loops_, use_loop, loop_scale, options,
      [this](int64_t id) { return params_[Index(id)].data(); }, make_edge, &problem);
  // Gauge: see SetFixedVertex.
  problem.SetParameterBlockConstant(params_[Index(fixed_vertex())].data());

  ceres::Solver::Options solver_options = SolverOptions(options);
  InterruptCallback interrupt_callback(interrupt);
  LogCallback log_callback;
  if (interrupt != nullptr) solver_options.callbacks.push_back(&interrupt_callback);
  if (options.log_progress) solver_options.callbacks.push_back(&log_callback);

  const std::vector<Vector8d> backup = params_;
  if (reduce) {
    reduction_timer = Timer();
    summary.initial_cost = FullCost(options, use_loop);
    reduction_seconds += reduction_timer.ElapsedMs() / 1000.0;
  }
  ceres::Solver::Summary ceres_summary;
  ceres::Solve(solver_options, &problem, &ceres_summary);

  summary.initial_cost = reduce ? summary.initial_cost : ceres_summary.initial_cost;
  summary.final_cost = ceres_summary.final_cost;
  summary.iterations = static_cast<int>(ceres_summary.iterations.size()) - 1;
  summary.ceres_message = ceres_summary.message;
  summary.status = StatusOf(ceres_summary, interrupt_callback.interrupted());
  // A NaN or infinite cost is no solution, whatever Ceres' termination says (a loss scale of
  // 1e-308 "converged" with cost -nan).
  if (summary.status != PoseGraphStatus::kFailed && !std::isfinite(ceres_summary.final_cost)) {
    summary.status = PoseGraphStatus::kFailed;
    summary.ceres_message = fmt::format("the cost is not finite ({})", ceres_summary.final_cost);
  }
  if (summary.status == PoseGraphStatus::kFailed) {
    params_ = backup;
    Logger().warn("pose graph solve failed: {}", ceres_summary.message);
  }
  if (reduce) {
    reduction_timer = Timer();
    if (summary.status != PoseGraphStatus::kFailed) {
      for (const internal::ReducedChain& chain : reduction.chains) {
        internal::RecoverInterior(chain, edges_,
                                  jet::Sim3<double>::FromArray(params_[chain.from].data()),
                                  jet::Sim3<double>::FromArray(params_[chain.to].data()), &params_);
      }
    }
    summary.final_cost = FullCost(options, use_loop);
    reduction_seconds += reduction_timer.ElapsedMs() / 1000.0;
  }
  summary.solve_seconds = ceres_summary.total_time_in_seconds + reduction_seconds;
  AdoptSolution(options, use_loop, &summary);
}

Matrix7d LoopEffectiveInformation(const LoopConstraint& loop) {
  Matrix7d info = loop.weight * loop.information;
  if (!loop.has_scale) {
    info.row(6).setZero();
    info.col(6).setZero();
  }
  return info;
}

PoseGraph BuildOdometryGraph(
    const std::vector<int64_t>& ids, const std::vector<Sim3d>& raw_world_from_keyframe,
    VertexType type, const OdometryWeighting& weighting,
    const std::vector<std::optional<Eigen::Matrix<double, 6, 6>>>& step_covariance) {
  weighting.Check();
  SL_CHECK_MSG(ids.size() == raw_world_from_keyframe.size(),
               "ids ({}) and poses ({}) differ in size", ids.size(),
               raw_world_from_keyframe.size());
  SL_CHECK_MSG(step_covariance.empty() || step_covariance.size() == ids.size(),
               "step covariances ({}) must be empty or one per keyframe ({})",
               step_covariance.size(), ids.size());
  PoseGraph graph(type);
  for (size_t i = 0; i < ids.size(); ++i) graph.AddVertex(ids[i], raw_world_from_keyframe[i]);
  for (size_t i = 1; i < ids.size(); ++i) {
    PoseGraphEdge edge;
    edge.from = ids[i - 1];
    edge.to = ids[i];
    edge.from_from_to = raw_world_from_keyframe[i - 1].Inverse() * raw_world_from_keyframe[i];
    if (!step_covariance.empty() && step_covariance[i]) {
      try {
        edge.information = weighting.InformationFromCovariance(*step_covariance[i]);
      } catch (const std::invalid_argument& e) {
        throw std::invalid_argument(
            fmt::format("odometry covariance of keyframe {}: {}", ids[i], e.what()));
      }
      edge.information_from_caller = true;
    } else {
      edge.information = weighting.Information(edge.from_from_to);
    }
    if (type != VertexType::kSim3) edge.from_from_to.scale = 1.0;
    graph.AddEdge(edge);
  }
  return graph;
}

LoopConstraint MakeLoopConstraintFromDirection(int64_t query_id, int64_t match_id,
                                               const Sim3d& raw_world_from_query,
                                               const Sim3d& raw_world_from_match,
                                               const Eigen::Quaterniond& match_from_query_rotation,
                                               const Eigen::Vector3d& unit_direction,
                                               double local_step_length,
                                               const DirectionLoopOptions& options) {
  options.Check();
  SL_CHECK_MSG(std::abs(unit_direction.norm() - 1.0) < 1e-6,
               "unit_direction must have norm 1, got {}", unit_direction.norm());
  SL_CHECK_MSG(local_step_length > 0 && std::isfinite(local_step_length),
               "local_step_length must be > 0, got {}", local_step_length);
  SL_CHECK_MSG(raw_world_from_query.scale > 0 && raw_world_from_match.scale > 0,
               "raw poses must have positive scale");
  // World units -> the match keyframe's frame units (the translation lives in that frame).
  const double magnitude =
      options.baseline_in_steps * local_step_length / raw_world_from_match.scale;
  LoopConstraint loop;
  loop.query_id = query_id;
  loop.match_id = match_id;
  loop.match_from_query = Sim3d(1.0, match_from_query_rotation, magnitude * unit_direction);
  loop.has_scale = false;
  loop.weight = options.weight;
  const double sigma_along = options.magnitude_sigma_fraction * magnitude;
  const double sigma_perp = options.direction_sigma_rad * magnitude;
  const Eigen::Matrix3d dd = unit_direction * unit_direction.transpose();
  loop.information.setZero();
  loop.information.topLeftCorner<3, 3>() =
      dd / (sigma_along * sigma_along) +
      (Eigen::Matrix3d::Identity() - dd) / (sigma_perp * sigma_perp);
  loop.information.block<3, 3>(3, 3) =
      Eigen::Matrix3d::Identity() / (options.rotation_sigma_rad * options.rotation_sigma_rad);
  return loop;
}

}  // namespace sparseloop
