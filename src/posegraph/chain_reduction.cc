#include "chain_reduction.h"

#include <Eigen/Cholesky>

#include "sparseloop/core/check.h"

namespace sparseloop::internal {
namespace {

using S3 = jet::Sim3<double>;

bool IsDiagonal(const Matrix7d& m) {
  for (int c = 0; c < 7; ++c) {
    for (int r = 0; r < 7; ++r) {
      if (r != c && m(r, c) != 0.0) return false;
    }
  }
  return true;
}

// True when the information is positive definite (rank-deficient 2D-in-7D edges have no
// covariance and cannot be chained).
bool Chainable(const Matrix7d& information, bool diagonal) {
  if (diagonal) return information.diagonal().minCoeff() > 0.0;
  return Eigen::LLT<Matrix7d>(information).info() == Eigen::Success;
}

}  // namespace

Matrix7d StepCovariance(const PoseGraphEdge& edge, bool reversed) {
  Matrix7d cov;
  if (IsDiagonal(edge.information)) {
    cov = Matrix7d(edge.information.diagonal().cwiseInverse().asDiagonal());
  } else {
    cov = edge.information.llt().solve(Matrix7d::Identity());
  }
  if (!reversed) return cov;
  // Inverting Z exp(e) gives Z^-1 exp(-Ad(Z) e).
  const Matrix7d ad = Sim3EdgeCost::Adjoint(ToJetSim3(edge.from_from_to));
  return ad * cov * ad.transpose();
}

namespace {

// Incident edges of every vertex, compressed: incident[offset[v] .. offset[v + 1]).
struct Incidence {
  std::vector<size_t> offset, incident;
};

Incidence BuildIncidence(const std::vector<std::array<size_t, 2>>& ends, size_t n) {
  Incidence g;
  g.offset.assign(n + 1, 0);
  for (size_t e = 0; e < ends.size(); ++e) {
    SL_CHECK_MSG(ends[e][0] < n && ends[e][1] < n, "edge {} has a vertex index out of range", e);
    ++g.offset[ends[e][0] + 1];
    ++g.offset[ends[e][1] + 1];
  }
  for (size_t v = 0; v < n; ++v) g.offset[v + 1] += g.offset[v];
  g.incident.resize(g.offset[n]);
  std::vector<size_t> fill(g.offset.begin(), g.offset.end() - 1);
  for (size_t e = 0; e < ends.size(); ++e) {
    g.incident[fill[ends[e][0]]++] = e;
    g.incident[fill[ends[e][1]]++] = e;
  }
  return g;
}

// The chain's composed measurement and first-order covariance (as its square-root information),
// accumulated from the last step backwards.
void ComposeChain(const std::vector<PoseGraphEdge>& edges, const std::vector<bool>& diagonal,
                  ReducedChain* chain) {
  S3 suffix;  // Z_{i+1} ... Z_k
  Matrix7d sigma = Matrix7d::Zero();
  for (size_t i = chain->steps.size(); i-- > 0;) {
    const Matrix7d a = Sim3EdgeCost::Adjoint(suffix.Inverse());
    const size_t edge = chain->step_edges[i];
    if (diagonal[edge] && !chain->step_reversed[i]) {
      // a * diag(c) * a^T: one 7x7 product instead of two.
      const Matrix7d scaled = a * edges[edge].information.diagonal().cwiseInverse().asDiagonal();
      sigma.noalias() += scaled * a.transpose();
    } else {
      sigma.noalias() += a * StepCovariance(edges[edge], chain->step_reversed[i]) * a.transpose();
    }
    suffix = chain->steps[i] * suffix;
  }
  chain->from_from_to = suffix;
  sigma = 0.5 * (sigma + sigma.transpose());
  const Eigen::LLT<Matrix7d> llt(sigma);
  SL_CHECK_MSG(llt.info() == Eigen::Success, "chain covariance is not positive definite");
  // Sigma = L L^T, so S = L^-1 gives S^T S = Sigma^-1.
  chain->sqrt_information = llt.matrixL().solve(Matrix7d::Identity());
}

// Keeps every vertex that is not a chain vertex (exactly two chainable edges, to two different
// neighbours).
void KeepNonChainVertices(const Incidence& g, const std::vector<std::array<size_t, 2>>& ends,
                          const std::vector<bool>& chainable, std::vector<bool>* kept) {
  const auto other_end = [&](size_t e, size_t v) {
    return ends[e][0] == v ? ends[e][1] : ends[e][0];
  };
  for (size_t v = 0; v + 1 < g.offset.size(); ++v) {
    if ((*kept)[v]) continue;
    const size_t* inc = g.incident.data() + g.offset[v];
    const bool chain_vertex = g.offset[v + 1] - g.offset[v] == 2 && chainable[inc[0]] &&
                              chainable[inc[1]] && other_end(inc[0], v) != other_end(inc[1], v);
    if (!chain_vertex) (*kept)[v] = true;
  }
}

// A chain that came back to its start (a ring of chain vertices): its last interior vertex is
// kept, so that the chain has two distinct ends and its last edge becomes a direct edge.
void BreakRing(ReducedChain* chain, ChainReduction* out, std::vector<bool>* in_chain) {
  SL_CHECK(!chain->interior.empty());
  const size_t last = chain->interior.back();
  chain->interior.pop_back();
  (*in_chain)[last] = false;
  out->kept[last] = true;
  chain->to = last;
  out->direct_edges.push_back(chain->step_edges.back());
  chain->steps.pop_back();
  chain->step_edges.pop_back();
  chain->step_reversed.pop_back();
}

// Walks chains from kept vertices, one edge at a time, and records them in a ChainReduction.
class ChainWalker {
 public:
  // Where the next chain starts when a walk was cut at max_chain_length.
  struct Next {
    bool more = false;
    size_t vertex = 0, edge = 0;
  };

  ChainWalker(const std::vector<PoseGraphEdge>& edges,
              const std::vector<std::array<size_t, 2>>& ends, const Incidence& graph,
              const std::vector<bool>& diagonal, int max_chain_length, ChainReduction* out)
      : edges_(edges),
        ends_(ends),
        graph_(graph),
        diagonal_(diagonal),
        max_chain_length_(max_chain_length),
        out_(out),
        edge_done_(edges.size(), false),
        in_chain_(graph.offset.size() - 1, false) {}

  bool edge_done(size_t e) const { return edge_done_[e]; }
  bool in_chain(size_t v) const { return in_chain_[v]; }

  // Walks one chain from kept vertex `start` along `first_edge`. When the chain is cut at
  // max_chain_length, returns the cut vertex and its other edge (the next chain to walk).
  Next Walk(size_t start, size_t first_edge) {
    edge_done_[first_edge] = true;
    if (out_->kept[OtherEnd(first_edge, start)]) {
      out_->direct_edges.push_back(first_edge);
      return {};
    }
    Next next_chain;
    ReducedChain chain;
    chain.from = start;
    size_t u = start, e = first_edge;
    for (;;) {
      AddStep(u, e, &chain);
      const size_t w = OtherEnd(e, u);
      if (out_->kept[w]) {
        chain.to = w;
        break;
      }
      if (static_cast<int>(chain.steps.size()) == max_chain_length_) {
        out_->kept[w] = true;  // cut the chain here; w starts the next one
        next_chain = {true, w, OtherEdge(w, e)};
        chain.to = w;
        break;
      }
      chain.interior.push_back(w);
      in_chain_[w] = true;
      const size_t next = OtherEdge(w, e);
      edge_done_[next] = true;
      u = w;
      e = next;
    }
    if (chain.to == chain.from) BreakRing(&chain, out_, &in_chain_);
    ComposeChain(edges_, diagonal_, &chain);
    out_->chains.push_back(std::move(chain));
    return next_chain;
  }

 private:
  size_t OtherEnd(size_t e, size_t v) const { return ends_[e][0] == v ? ends_[e][1] : ends_[e][0]; }
  // The other edge of a chain vertex (exactly two edges).
  size_t OtherEdge(size_t v, size_t e) const {
    const size_t first = graph_.incident[graph_.offset[v]];
    return first == e ? graph_.incident[graph_.offset[v] + 1] : first;
  }
  // The step along e leaving u: the measurement, inverted when e points into u.
  void AddStep(size_t u, size_t e, ReducedChain* chain) const {
    const bool reversed = ends_[e][0] != u;
    const S3 measured = ToJetSim3(edges_[e].from_from_to);
    chain->steps.push_back(reversed ? measured.Inverse() : measured);
    chain->step_edges.push_back(e);
    chain->step_reversed.push_back(reversed);
  }

  const std::vector<PoseGraphEdge>& edges_;
  const std::vector<std::array<size_t, 2>>& ends_;
  const Incidence& graph_;
  const std::vector<bool>& diagonal_;
  const int max_chain_length_;
  ChainReduction* out_;
  std::vector<bool> edge_done_;
  std::vector<bool> in_chain_;
};

}  // namespace

ChainReduction ReduceChains(const std::vector<PoseGraphEdge>& edges,
                            const std::vector<std::array<size_t, 2>>& ends,
                            std::vector<bool> must_keep, int max_chain_length) {
  SL_CHECK_MSG(max_chain_length >= 1, "max_chain_length must be >= 1, got {}", max_chain_length);
  SL_CHECK_MSG(edges.size() == ends.size(), "edges ({}) and ends ({}) differ in size", edges.size(),
               ends.size());
  const size_t n = must_keep.size();
  const Incidence graph = BuildIncidence(ends, n);
  std::vector<bool> diagonal(edges.size()), chainable(edges.size());
  for (size_t e = 0; e < edges.size(); ++e) {
    diagonal[e] = IsDiagonal(edges[e].information);
    chainable[e] = Chainable(edges[e].information, diagonal[e]);
  }

  ChainReduction out;
  out.kept = std::move(must_keep);
  KeepNonChainVertices(graph, ends, chainable, &out.kept);
  ChainWalker walker(edges, ends, graph, diagonal, max_chain_length, &out);
  std::vector<size_t> queue;
  for (size_t v = 0; v < n; ++v)
    if (out.kept[v]) queue.push_back(v);
  for (;;) {
    for (size_t qi = 0; qi < queue.size(); ++qi) {
      const size_t a = queue[qi];
      for (size_t j = graph.offset[a]; j < graph.offset[a + 1]; ++j) {
        if (walker.edge_done(graph.incident[j])) continue;
        for (auto next = walker.Walk(a, graph.incident[j]);
             next.more && !walker.edge_done(next.edge);) {
          next = walker.Walk(next.vertex, next.edge);
        }
      }
    }
    // Chain vertices no walk reached form rings without a kept vertex: keep one of each.
    queue.clear();
    for (size_t v = 0; v < n && queue.empty(); ++v) {
      if (!out.kept[v] && !walker.in_chain(v)) {
        out.kept[v] = true;
        queue.push_back(v);
      }
    }
    if (queue.empty()) break;
  }
  for (size_t v = 0; v < n; ++v) out.num_kept += out.kept[v] ? 1 : 0;
  return out;
}

void RecoverInterior(const ReducedChain& chain, const std::vector<PoseGraphEdge>& edges,
                     const jet::Sim3<double>& world_from_first,
                     const jet::Sim3<double>& world_from_last, std::vector<Vector8d>* params) {
  const size_t interior = chain.interior.size();
  if (interior == 0) return;
  const jet::Vector7<double> delta =
      (chain.from_from_to.Inverse() * (world_from_first.Inverse() * world_from_last)).Log();
  // lambda = Sigma^-1 delta = S^T S delta; r_i = Sigma_i A_i^T lambda with A_i from the suffix
  // Z_{i+1} ... Z_k, walked backwards.
  const jet::Vector7<double> lambda =
      chain.sqrt_information.transpose() * (chain.sqrt_information * delta);
  std::vector<jet::Vector7<double>> r(interior);
  S3 suffix = chain.steps.back();  // the suffix of step k - 1 (the last interior vertex)
  for (size_t i = interior; i-- > 0;) {
    const jet::Vector7<double> mu = Sim3EdgeCost::Adjoint(suffix.Inverse()).transpose() * lambda;
    const PoseGraphEdge& edge = edges[chain.step_edges[i]];
    if (!chain.step_reversed[i] && IsDiagonal(edge.information)) {
      r[i] = mu.cwiseQuotient(edge.information.diagonal());
    } else {
      r[i] = StepCovariance(edge, chain.step_reversed[i]) * mu;
    }
    suffix = chain.steps[i] * suffix;
  }
  S3 pose = world_from_first;
  for (size_t i = 0; i < interior; ++i) {
    pose = pose * chain.steps[i] * S3::Exp(r[i]);
    pose.ToArray((*params)[chain.interior[i]].data());
  }
}

}  // namespace sparseloop::internal
