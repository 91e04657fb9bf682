// Pairwise consistency maximisation (PCM) of loop constraints.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "sparseloop/core/check.h"
#include "sparseloop/core/statistics.h"
#include "sparseloop/posegraph/pose_graph.h"

namespace sparseloop {
namespace {

// The directions an information matrix observes: eigenvalues above 1e-9 of the largest.
template <int N>
int ObservableDof(const Eigen::Matrix<double, N, N>& info) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> eig(info);
  const double tol = 1e-9 * std::max(eig.eigenvalues().maxCoeff(), 0.0);
  return static_cast<int>((eig.eigenvalues().array() > tol).count());
}

// Maximum clique: greedy by degree, then exact branch and bound when small enough. Among cliques
// of the same size the one with the larger sum of loop weights wins: two loops that contradict
// each other (a strong metric loop of 80 inliers and a weak two-view one of 24) are each a
// clique of one, and the order they were found in must not decide.
class CliqueFinder {
 public:
  CliqueFinder(const std::vector<std::vector<bool>>& adj, const std::vector<double>& weights)
      : adj_(adj), weights_(weights), n_(adj.size()) {}

  bool Better(const std::vector<size_t>& a, const std::vector<size_t>& b) const {
    if (a.size() != b.size()) return a.size() > b.size();
    return Weight(a) > Weight(b) + 1e-12;
  }

  std::vector<size_t> Greedy() const {
    std::vector<size_t> order(n_);
    std::iota(order.begin(), order.end(), 0);
    std::vector<size_t> degree(n_, 0);
    for (size_t i = 0; i < n_; ++i)
      for (size_t j = 0; j < n_; ++j) degree[i] += adj_[i][j] ? 1 : 0;
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
      return degree[a] != degree[b] ? degree[a] > degree[b] : weights_[a] > weights_[b];
    });
    std::vector<size_t> best;
    std::vector<bool> in_best(n_, false);
    // Seed from each vertex (in degree order), grow greedily; keep the largest.
    for (size_t seed : order) {
      if (degree[seed] + 1 < best.size()) break;
      // A vertex of `best` whose neighbours are exactly the rest of it grows into `best` again
      // (every seed of a complete graph: without this n^3 work, 2,000 loops 4.4 s per solve).
      if (in_best[seed] && degree[seed] + 1 == best.size()) continue;
      std::vector<size_t> clique{seed};
      for (size_t v : order) {
        if (v == seed) continue;
        bool ok = true;
        for (size_t i = 0; ok && i < clique.size(); ++i) ok = adj_[clique[i]][v];
        if (ok) clique.push_back(v);
      }
      if (Better(clique, best)) {
        best = clique;
        in_best.assign(n_, false);
        for (size_t v : best) in_best[v] = true;
      }
    }
    return best;
  }

  std::vector<size_t> Exact(std::vector<size_t> best, size_t max_steps) {
    best_ = std::move(best);
    steps_ = 0;
    max_steps_ = max_steps;
    std::vector<size_t> candidates(n_);
    std::iota(candidates.begin(), candidates.end(), 0);
    std::vector<size_t> current;
    Expand(current, candidates);
    return best_;
  }

 private:
  void Expand(std::vector<size_t>& current, std::vector<size_t> candidates) {
    if (++steps_ > max_steps_) return;
    while (!candidates.empty()) {
      if (current.size() + candidates.size() < best_.size()) return;
      const size_t v = candidates.back();
      candidates.pop_back();
      std::vector<size_t> next;
      for (size_t u : candidates)
        if (adj_[v][u]) next.push_back(u);
      current.push_back(v);
      if (next.empty()) {
        if (Better(current, best_)) best_ = current;
      } else {
        Expand(current, next);
      }
      current.pop_back();
    }
  }

  double Weight(const std::vector<size_t>& clique) const {
    double w = 0.0;
    for (size_t v : clique) w += weights_[v];
    return w;
  }

  const std::vector<std::vector<bool>>& adj_;
  const std::vector<double>& weights_;
  size_t n_;
  std::vector<size_t> best_;
  size_t steps_ = 0;
  size_t max_steps_ = 0;
};

// Prefix sums over the raw trajectory for the chain covariance: translation and rotation
// variances of the steps; the lever-arm weights w_k = rotation + scale variance of the step
// leaving vertex k, with sum w_k, sum w_k p_k, sum w_k |p_k|^2.
struct ChainStatistics {
  std::vector<double> t2, r2, w0, w2;
  std::vector<Eigen::Vector3d> w1;
  double ss2 = 0.0;                 // scale variance per step
  const std::vector<Sim3d>& poses;  // the raw poses the sums are over

  ChainStatistics(const std::vector<Sim3d>& raw_poses, const std::vector<double>& step_t2,
                  const std::vector<double>& step_r2, double sr2, double scale_variance)
      : t2(raw_poses.size(), 0.0),
        r2(raw_poses.size(), 0.0),
        w0(raw_poses.size() + 1, 0.0),
        w2(raw_poses.size() + 1, 0.0),
        w1(raw_poses.size() + 1, Eigen::Vector3d::Zero()),
        ss2(scale_variance),
        poses(raw_poses) {
    const size_t m = raw_poses.size();
    for (size_t i = 0; i < m; ++i) {
      if (i > 0) {
        t2[i] = t2[i - 1] + step_t2[i];
        r2[i] = r2[i - 1] + step_r2[i];
      }
      const Eigen::Vector3d& p = raw_poses[i].translation;
      const double w = (i + 1 < m ? step_r2[i + 1] : sr2) + ss2;
      w0[i + 1] = w0[i] + w;
      w1[i + 1] = w1[i] + w * p;
      w2[i + 1] = w2[i] + w * p.squaredNorm();
    }
  }

  // Diagonal covariance of the chain from vertex index i to j, expressed at j.
  Eigen::Matrix<double, 7, 1> Covariance(size_t i, size_t j) const {
    if (i > j) std::swap(i, j);
    Eigen::Matrix<double, 7, 1> cov = Eigen::Matrix<double, 7, 1>::Zero();
    const Eigen::Vector3d& pj = poses[j].translation;
    // sum_{k in [i, j)} w_k |p_j - p_k|^2: the lever arm of rotation / scale drift at step k.
    const double lever =
        (w0[j] - w0[i]) * pj.squaredNorm() - 2.0 * pj.dot(w1[j] - w1[i]) + (w2[j] - w2[i]);
    cov.head<3>().setConstant(t2[j] - t2[i] + std::max(lever, 0.0));
    cov.segment<3>(3).setConstant(r2[j] - r2[i]);
    cov[6] = static_cast<double>(j - i) * ss2;
    return cov;
  }
};

// Per-loop marginal variances from the (effective) information. A diagonal information is
// inverted per component; a full one (a loop whose information came from its inliers) through
// its eigen-decomposition: marginal variances of the observable part, infinite for every
// component an unobservable direction touches (1 / diag would be the conditional variance, too
// small when the components are correlated).
Eigen::Matrix<double, 7, 1> LoopMarginalVariances(const LoopConstraint& loop) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const Matrix7d info = LoopEffectiveInformation(loop);
  Eigen::Matrix<double, 7, 1> cov;
  if (info.isDiagonal(0.0)) {
    for (int d = 0; d < 7; ++d) cov[d] = info(d, d) > 0 ? 1.0 / info(d, d) : kInf;
    return cov;
  }
  const Eigen::SelfAdjointEigenSolver<Matrix7d> eig(info);
  const double tol = 1e-9 * std::max(eig.eigenvalues().maxCoeff(), 0.0);
  cov.setZero();
  for (int k = 0; k < 7; ++k) {
    const double lambda = eig.eigenvalues()[k];
    const Eigen::Matrix<double, 7, 1> v = eig.eigenvectors().col(k);
    for (int d = 0; d < 7; ++d) {
      if (lambda > tol) {
        cov[d] += v[d] * v[d] / lambda;
      } else if (std::abs(v[d]) > 1e-6) {
        cov[d] = kInf;
      }
    }
  }
  return cov;
}

// PcmOptions::scale_profile. A loop's scale variance below this is floored: the profile must not
// follow one loop's depths (a 6-inlier Sim(3)) exactly; log-scale units.
constexpr double kProfileMinLoopSigma = 0.05;
// Huber threshold of the profile's loop residuals (sigmas) and the reweighting rounds: a loop
// whose scale disagrees with the others (a false loop) bends the profile little.
constexpr double kProfileHuber = 2.0;
constexpr int kProfileRounds = 5;
// A cached adjacency stays valid while the profile moves by at most this (log-scale).
constexpr double kProfileTolerance = 0.01;

// True when the pairs computed with profile `old` still hold under `now`: the same on the
// vertices both cover (a pair only reads the raw poses up to its own vertices).
bool SameProfile(const std::vector<double>& old, const std::vector<double>& now) {
  if (old.empty() != now.empty()) return false;
  for (size_t k = 0; k < std::min(old.size(), now.size()); ++k)
    if (std::abs(old[k] - now[k]) > kProfileTolerance) return false;
  return true;
}

}  // namespace

void PoseGraph::PcmLoopVariances(std::vector<Vector7d>* variances) const {
  for (size_t k = variances->size(); k < loops_.size(); ++k)
    variances->push_back(LoopMarginalVariances(loops_[k]));
}

std::vector<double> PoseGraph::PcmScaleProfile(const PcmOptions& options,
                                               const std::vector<Vector7d>& variances) const {
  const size_t m = ids_.size();
  if (!options.scale_profile || type_ != VertexType::kSim3 || m < 2) return {};
  struct Observation {
    size_t query, match;
    double log_scale, weight;
  };
  std::vector<Observation> observations;
  for (size_t k = 0; k < loops_.size(); ++k) {
    const LoopConstraint& l = loops_[k];
    const double variance = variances[k][6];
    if (!std::isfinite(variance) || !(l.match_from_query.scale > 0)) continue;  // free scale
    observations.push_back({Index(l.query_id), Index(l.match_id),
                            std::log(l.match_from_query.scale),
                            1.0 / std::max(variance, kProfileMinLoopSigma * kProfileMinLoopSigma)});
  }
  if (observations.empty()) return {};
  // Unknowns l_k = log of the factor taking raw units at vertex k to those at vertex 0. Each
  // loop: l_query - l_match = log s (its Sim(3) maps query units to match units); each step a
  // random walk of step_scale_sigma; l_0 = 0. Solved on the loops' vertices only (and vertex
  // 0): a random walk between two of them is one difference of variance gap x sigma^2, and the
  // vertices between are its linear interpolation (exact for a random walk); constant after the
  // last. Small (<= 2 x loops + 1 unknowns) whatever the trajectory's length.
  std::vector<size_t> keys{0};
  for (const Observation& o : observations) {
    keys.push_back(o.query);
    keys.push_back(o.match);
  }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  for (Observation& o : observations) {  // vertex indices -> indices into keys
    o.query =
        static_cast<size_t>(std::lower_bound(keys.begin(), keys.end(), o.query) - keys.begin());
    o.match =
        static_cast<size_t>(std::lower_bound(keys.begin(), keys.end(), o.match) - keys.begin());
  }
  const auto nk = static_cast<Eigen::Index>(keys.size());
  const double step_variance = options.step_scale_sigma * options.step_scale_sigma;
  std::vector<double> robust(observations.size(), 1.0);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(nk);
  for (int round = 0; round < kProfileRounds; ++round) {
    std::vector<Eigen::Triplet<double>> h;
    Eigen::VectorXd g = Eigen::VectorXd::Zero(nk);
    auto add_difference = [&](Eigen::Index i, Eigen::Index j, double w, double y) {
      h.emplace_back(i, i, w);  // w (x_i - x_j - y)^2
      h.emplace_back(j, j, w);
      h.emplace_back(i, j, -w);
      h.emplace_back(j, i, -w);
      g[i] += w * y;
      g[j] -= w * y;
    };
    h.emplace_back(0, 0, 1e6 / step_variance);  // the gauge: l_0 = 0
    for (Eigen::Index k = 1; k < nk; ++k) {
      const double gap =
          static_cast<double>(keys[static_cast<size_t>(k)] - keys[static_cast<size_t>(k - 1)]);
      add_difference(k, k - 1, 1.0 / (gap * step_variance), 0.0);
    }
    for (size_t i = 0; i < observations.size(); ++i) {
      const Observation& o = observations[i];
      if (o.query != o.match)
        add_difference(static_cast<Eigen::Index>(o.query), static_cast<Eigen::Index>(o.match),
                       o.weight * robust[i], o.log_scale);
    }
    Eigen::SparseMatrix<double> hessian(nk, nk);
    hessian.setFromTriplets(h.begin(), h.end());
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(hessian);
    if (ldlt.info() != Eigen::Success) return {};
    x = ldlt.solve(g);
    for (size_t i = 0; i < observations.size(); ++i) {
      const Observation& o = observations[i];
      const double r = std::abs(x[static_cast<Eigen::Index>(o.query)] -
                                x[static_cast<Eigen::Index>(o.match)] - o.log_scale) *
                       std::sqrt(o.weight);
      robust[i] = r <= kProfileHuber ? 1.0 : kProfileHuber / r;
    }
  }
  if (!x.allFinite()) return {};
  std::vector<double> profile(m, x[nk - 1]);
  for (Eigen::Index k = 0; k + 1 < nk; ++k) {
    const size_t lo = keys[static_cast<size_t>(k)], hi = keys[static_cast<size_t>(k + 1)];
    for (size_t v = lo; v < hi; ++v)
      profile[v] =
          x[k] + (x[k + 1] - x[k]) * static_cast<double>(v - lo) / static_cast<double>(hi - lo);
  }
  return profile;
}

void PoseGraph::ExtendPcmAdjacency(const PcmOptions& options, size_t from,
                                   const std::vector<Vector7d>& variances,
                                   const std::vector<double>& log_scale,
                                   std::vector<std::vector<bool>>* adj,
                                   OdometryResiduals* odometry) const {
  const size_t n = loops_.size();
  adj->resize(n);
  for (auto& row : *adj) row.resize(n, false);
  odometry->chi2.resize(n, 0.0);
  odometry->dof.resize(n, 0);
  if (from >= n) return;
  // Per-step variances (step k: vertex k-1 -> k, insertion order): the model's, or those of the
  // caller's covariance where the step's edge carries one.
  const size_t m = ids_.size();
  const bool sim3 = type_ == VertexType::kSim3;
  const double ft2 = options.step_translation_fraction * options.step_translation_fraction;
  const double sr2 = options.step_rotation_sigma_rad * options.step_rotation_sigma_rad;
  const double ss2 = sim3 ? options.step_scale_sigma * options.step_scale_sigma : 0.0;
  // PcmOptions::scale_profile: the raw poses with each step in the units of the first vertex
  // (the loops follow below), or the raw poses as they are.
  const bool rescale = sim3 && log_scale.size() == m;
  std::vector<double> step_t2(m, 0.0), step_r2(m, sr2);
  for (size_t k = 1; k < m; ++k) {
    step_t2[k] = ft2 * (raw_poses_[k].translation - raw_poses_[k - 1].translation).squaredNorm();
  }
  for (const PoseGraphEdge& e : edges_) {
    if (!e.information_from_caller) continue;
    const size_t a = Index(e.from), b = Index(e.to);
    if (std::max(a, b) != std::min(a, b) + 1) continue;  // not a step
    const Eigen::Matrix<double, 6, 6> cov = e.information.topLeftCorner<6, 6>().inverse();
    const size_t k = std::max(a, b);
    step_t2[k] = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov.topLeftCorner<3, 3>())
                     .eigenvalues()
                     .maxCoeff();
    step_r2[k] = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov.bottomRightCorner<3, 3>())
                     .eigenvalues()
                     .maxCoeff();
  }
  // The odometry test reads the raw poses (its own calibration holds the scale drift); the
  // pairwise test reads them rescaled by the profile, each step's translation (and its variance)
  // in the units of the first vertex, when there is one.
  const ChainStatistics raw_chains(raw_poses_, step_t2, step_r2, sr2, ss2);
  std::vector<Sim3d> rescaled;
  std::vector<double> rescaled_t2;
  std::optional<ChainStatistics> rescaled_chains;
  if (rescale) {
    rescaled = raw_poses_;
    rescaled_t2 = step_t2;
    for (size_t k = 1; k < m; ++k) {
      const double f = std::exp(0.5 * (log_scale[k - 1] + log_scale[k]));
      rescaled[k].translation = rescaled[k - 1].translation +
                                f * (raw_poses_[k].translation - raw_poses_[k - 1].translation);
      rescaled_t2[k] *= f * f;
    }
    rescaled_chains.emplace(rescaled, rescaled_t2, step_r2, sr2, ss2);
  }
  const std::vector<Sim3d>& poses = rescale ? rescaled : raw_poses_;
  const ChainStatistics& chains = rescale ? *rescaled_chains : raw_chains;
  std::vector<double> thresholds(8, 0.0);
  for (int dof = 1; dof <= 7; ++dof) thresholds[dof] = ChiSquareQuantile(options.confidence, dof);
  // The single-loop odometry test: the loop's residual at the raw poses against zero, with
  // the loop's full information (its marginal variances alone would call a loop whose rotation
  // is well known only together with its translation, as a two-view Sim(3) without depths is,
  // uninformative) plus the chain's diagonal covariance: (chain + info^-1)^-1 = C - C (info + C)^-1
  // C with C = chain^-1, defined also where the loop's information is singular.
  for (size_t k = from; options.odometry_check && k < n; ++k) {
    const LoopConstraint& l = loops_[k];
    const size_t q = Index(l.query_id), m = Index(l.match_id);
    // The loop's residual at the raw poses (as CheckLoop: the frame its information is in).
    const Vector6d e =
        (l.match_from_query.Inverse() * raw_poses_[m].Inverse() * raw_poses_[q]).Log().head<6>();
    // Translation and rotation; the scale marginalised out (see PcmOptions::odometry_check).
    const Matrix7d info7 = LoopEffectiveInformation(l);
    Eigen::Matrix<double, 6, 6> info = info7.topLeftCorner<6, 6>();
    if (info7(6, 6) > 0) info -= info7.block<6, 1>(0, 6) * info7.block<1, 6>(6, 0) / info7(6, 6);
    const Eigen::Matrix<double, 7, 1> chain = raw_chains.Covariance(m, q);
    const Eigen::Matrix<double, 6, 6> c =
        chain.head<6>().cwiseMax(1e-12).cwiseInverse().asDiagonal();
    const Eigen::Matrix<double, 6, 6> weight = c - c * (info + c).ldlt().solve(c);
    const double chi2 = e.dot(weight * e);
    // A residual that is not finite fails (as in the pairwise test), and the median stays defined.
    odometry->chi2[k] = std::isnan(chi2) ? std::numeric_limits<double>::infinity() : chi2;
    odometry->dof[k] = ObservableDof<6>(info);
  }
  // Each loop in the poses' units (PcmOptions::scale_profile: a query unit is e^l_q, a match
  // unit e^l_m units of vertex 0) with its marginal variances (the translation's are in query
  // units: the tangent of a right perturbation).
  std::vector<Sim3d> z(n);
  std::vector<Eigen::Matrix<double, 7, 1>> z_cov(n);
  for (size_t k = 0; k < n; ++k) {
    z[k] = loops_[k].match_from_query;
    z_cov[k] = variances[k];
    if (!rescale) continue;
    const double lq = log_scale[Index(loops_[k].query_id)];
    const double lm = log_scale[Index(loops_[k].match_id)];
    // A loop that leaves its scale free (PnP: it says 1) takes the profile's, 1 in these units.
    z[k].scale = std::isfinite(z_cov[k][6]) ? z[k].scale * std::exp(lm - lq) : 1.0;
    z[k].translation *= std::exp(lm);
    z_cov[k].head<3>() *= std::exp(2.0 * lq);
  }
  // Only pairs with at least one loop in [from, n): the others were computed before and cannot
  // have changed (loops and raw poses are append-only, the chain statistics of a pair only read
  // raw poses up to its own vertices; with the profile, see PcmConsistentLoopsIncremental).
  for (size_t a = 0; a < n; ++a) {
    const LoopConstraint& la = loops_[a];
    const size_t qa = Index(la.query_id), ma = Index(la.match_id);
    const Eigen::Matrix<double, 7, 1>& cov_a = z_cov[a];
    for (size_t b = std::max(a + 1, from); b < n; ++b) {
      const LoopConstraint& lb = loops_[b];
      const size_t qb = Index(lb.query_id), mb = Index(lb.match_id);
      // ma_from_qa * qa_from_qb * qb_from_mb * mb_from_ma == identity for consistent loops.
      const Sim3d left = z[a] * (poses[qa].Inverse() * poses[qb]);
      const Sim3d right = z[b].Inverse() * (poses[mb].Inverse() * poses[ma]);
      const Sim3d cycle = left * right;
      Vector7d e = cycle.Log();
      if (!sim3) e[6] = 0.0;
      const Eigen::Matrix<double, 7, 1>& cov_b = z_cov[b];
      const Eigen::Matrix<double, 7, 1> cov =
          cov_a + cov_b + chains.Covariance(qa, qb) + chains.Covariance(ma, mb);
      // PcmOptions::free_scale_prior: a loop that leaves its relative scale free (PnP against
      // the match's points: the query side has no depth) says scale 1; under scale drift that is
      // wrong by the scale change between match and query, and the cycle's translation inherits
      // the error times a lever arm. Each such loop adds its scale prior (the chain's scale
      // variance between its match and query) along that lever arm to the translation covariance.
      std::vector<std::pair<Eigen::Vector3d, double>> free;
      if (options.free_scale_prior && sim3 && std::isinf(cov_a[6])) {
        // exp(sigma_a) scales q_a_from_m_a through the cycle: m_a seen from q_a.
        const Sim3d rest = (poses[qa].Inverse() * poses[qb]) * right;
        free.emplace_back(z[a].scale * (z[a].rotation * rest.translation),
                          chains.Covariance(ma, qa)[6]);
      }
      if (options.free_scale_prior && sim3 && std::isinf(cov_b[6])) {
        // exp(-sigma_b) scales q_b_from_m_a (m_a seen from q_b: the match chain).
        free.emplace_back(left.scale * (left.rotation * right.translation),
                          chains.Covariance(mb, qb)[6]);
      }
      const bool full_translation = !free.empty() && cov.head<3>().allFinite();
      double chi2 = 0.0;
      int dof = 0;
      for (int d = full_translation ? 3 : 0; d < 7; ++d) {
        if (!std::isfinite(cov[d]) || (d == 6 && !sim3)) continue;
        chi2 += e[d] * e[d] / std::max(cov[d], 1e-18);
        ++dof;
      }
      if (full_translation) {
        Eigen::Matrix3d c = cov.head<3>().cwiseMax(1e-18).asDiagonal();
        for (const auto& [u, variance] : free) c += variance * u * u.transpose();
        chi2 += e.head<3>().dot(c.ldlt().solve(e.head<3>()));
        dof += 3;
      }
      const bool consistent = dof == 0 || chi2 <= thresholds[dof];
      (*adj)[a][b] = (*adj)[b][a] = consistent;
    }
  }
}

namespace {

// The loops that pass the single-loop odometry test (PcmOptions::odometry_check): chi2 divided
// by the calibration max(1, median over the loops of chi2 / the model's median for its dof).
std::vector<size_t> PassOdometryTest(const PcmOptions& options, const std::vector<double>& chi2,
                                     const std::vector<int>& dof) {
  std::vector<double> median(7, 1.0), threshold(7, 0.0);  // by dof (at most 6)
  for (int d = 1; d <= 6; ++d) {
    median[d] = ChiSquareQuantile(0.5, d);
    threshold[d] = ChiSquareQuantile(options.odometry_check_confidence, d);
  }
  std::vector<size_t> pass;
  std::vector<double> ratio;
  for (size_t k = 0; k < chi2.size(); ++k)
    if (dof[k] > 0) ratio.push_back(chi2[k] / median[dof[k]]);
  double calibration = 1.0;
  if (!ratio.empty()) {
    std::nth_element(ratio.begin(), ratio.begin() + ratio.size() / 2, ratio.end());
    calibration = std::max(1.0, ratio[ratio.size() / 2]);
  }
  for (size_t k = 0; k < chi2.size(); ++k) {
    if (dof[k] == 0 || chi2[k] / calibration <= threshold[dof[k]]) pass.push_back(k);
  }
  return pass;
}

// The maximum clique among the loops that passed the single-loop test.
std::vector<size_t> MaximumClique(const std::vector<std::vector<bool>>& adj,
                                  const std::vector<size_t>& eligible,
                                  const std::vector<LoopConstraint>& loops,
                                  const PcmOptions& options) {
  const bool all = eligible.size() == loops.size();
  std::vector<std::vector<bool>> sub;
  if (!all) {
    sub.assign(eligible.size(), std::vector<bool>(eligible.size(), false));
    for (size_t a = 0; a < eligible.size(); ++a)
      for (size_t b = 0; b < eligible.size(); ++b) sub[a][b] = adj[eligible[a]][eligible[b]];
  }
  const std::vector<std::vector<bool>>& graph = all ? adj : sub;
  std::vector<double> weights;
  for (size_t k : eligible) weights.push_back(loops[k].weight);
  CliqueFinder finder(graph, weights);
  std::vector<size_t> clique = finder.Greedy();
  if (graph.size() <= options.max_exact_clique) clique = finder.Exact(clique, 2000000);
  for (size_t& v : clique) v = eligible[v];
  std::sort(clique.begin(), clique.end());
  return clique;
}

// The options the pairwise test depends on (max_exact_clique only affects the clique search).
bool SameConsistencyTest(const PcmOptions& a, const PcmOptions& b) {
  return a.confidence == b.confidence &&
         a.step_translation_fraction == b.step_translation_fraction &&
         a.step_rotation_sigma_rad == b.step_rotation_sigma_rad &&
         a.step_scale_sigma == b.step_scale_sigma && a.free_scale_prior == b.free_scale_prior &&
         a.odometry_check == b.odometry_check &&
         a.odometry_check_confidence == b.odometry_check_confidence &&
         a.scale_profile == b.scale_profile;
}

}  // namespace

LoopResidualCheck PoseGraph::CheckLoop(size_t index, double confidence) const {
  SL_CHECK_MSG(index < loops_.size(), "loop index {} out of range ({} loops)", index,
               loops_.size());
  const LoopConstraint& loop = loops_[index];
  LoopResidualCheck check;
  check.loop = index;
  check.query_id = loop.query_id;
  check.match_id = loop.match_id;
  const Sim3d& match = poses_[Index(loop.match_id)];
  const Sim3d& query = poses_[Index(loop.query_id)];
  Vector7d r = (loop.match_from_query.Inverse() * match.Inverse() * query).Log();
  if (type_ != VertexType::kSim3) r[6] = 0.0;
  const Matrix7d info = LoopEffectiveInformation(loop);
  check.chi2 = r.dot(info * r);
  check.dof = ObservableDof<7>(info);
  check.threshold = check.dof > 0 ? ChiSquareQuantile(confidence, check.dof) : 0.0;
  check.consistent = check.dof == 0 || check.chi2 <= check.threshold;
  check.translation_error = r.head<3>().norm();
  check.rotation_error_rad = r.segment<3>(3).norm();
  check.log_scale_error = r[6];
  return check;
}

std::vector<size_t> PoseGraph::PcmConsistentLoops(const PcmOptions& options) const {
  options.Check();
  if (loops_.empty()) return {};
  std::vector<std::vector<bool>> adj;
  OdometryResiduals odometry;
  std::vector<Vector7d> variances;
  PcmLoopVariances(&variances);
  ExtendPcmAdjacency(options, 0, variances, PcmScaleProfile(options, variances), &adj, &odometry);
  return MaximumClique(adj, PassOdometryTest(options, odometry.chi2, odometry.dof), loops_,
                       options);
}

std::vector<size_t> PoseGraph::PcmConsistentLoopsIncremental(const PcmOptions& options) {
  options.Check();
  if (loops_.empty()) return {};
  if (!pcm_cache_.valid || !SameConsistencyTest(pcm_cache_.options, options)) {
    pcm_cache_ = PcmCache{};
    pcm_cache_.valid = true;
    pcm_cache_.options = options;
  }
  // PcmOptions::scale_profile: the new pairs use today's profile; when it has moved by more than
  // kProfileTolerance from the one the cached pairs were computed with, every pair is recomputed.
  PcmLoopVariances(&pcm_cache_.variances);
  const std::vector<double> profile = PcmScaleProfile(options, pcm_cache_.variances);
  std::vector<double>& base = pcm_cache_.log_scale;
  size_t from = pcm_cache_.loops;
  if (!SameProfile(base, profile)) {
    from = 0;
    base = profile;
  }
  for (size_t k = base.size(); k < profile.size(); ++k) base.push_back(profile[k]);
  ExtendPcmAdjacency(options, from, pcm_cache_.variances, profile, &pcm_cache_.adj,
                     &pcm_cache_.odometry);
  pcm_cache_.loops = loops_.size();
  const OdometryResiduals& odometry = pcm_cache_.odometry;
  return MaximumClique(pcm_cache_.adj, PassOdometryTest(options, odometry.chi2, odometry.dof),
                       loops_, options);
}

}  // namespace sparseloop
