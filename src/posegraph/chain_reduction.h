#pragma once
// Chain reduction of Sim(3) pose graphs (private to the posegraph module; PoseGraph::Optimize
// uses it when PoseGraphOptions::reduce_chains is set).
//
// A SLAM pose graph is mostly chains: between two loop ends, hundreds of keyframes are joined
// only by their consecutive odometry edges. Such a vertex (exactly two edges, no loop, not the
// gauge) adds 7 unknowns to every linear solve but no information that its chain does not carry.
// The solve runs on the graph of the other ("kept") vertices, each chain of edges between two kept
// vertices replaced by one composed edge:
//   Z = Z_1 ... Z_k,   Sigma = sum_i A_i Sigma_i A_i^T,   A_i = Ad((Z_{i+1} ... Z_k)^-1)
// (first-order propagation of right perturbations Z_i exp(e_i), e_i ~ N(0, Sigma_i); Ad is the
// Sim(3) adjoint of edge_error.h), with information Sigma^-1. Afterwards the interior vertices are
// recovered from the solved chain ends as the conditional mean of the linearised chain: with
// delta = log(Z^-1 inv(T_a) T_b), the step residuals minimising sum_i r_i^T Sigma_i^-1 r_i subject
// to sum_i A_i r_i = delta are r_i = Sigma_i A_i^T Sigma^-1 delta, and T_i = T_{i-1} Z_i exp(r_i).
// For a linear-Gaussian chain this is exact marginalisation and back-substitution; on Sim(3) the
// difference to the full solve is of second order in the correction per chain, which
// `max_chain_length` keeps small (tests/posegraph/chain_reduction_test.cc measures it).
#include <array>
#include <cstddef>
#include <vector>

#include "posegraph/edge_error.h"
#include "posegraph/sim3_jet.h"
#include "sparseloop/posegraph/pose_graph.h"

namespace sparseloop::internal {

struct ReducedChain {
  size_t from = 0;                       // kept vertex index where the chain starts
  size_t to = 0;                         // kept vertex index where it ends (!= from)
  std::vector<size_t> interior;          // vertex indices in chain order (k - 1 of them)
  std::vector<jet::Sim3<double>> steps;  // k steps: v_{i-1}_from_v_i (v_0 = from, v_k = to)
  std::vector<size_t> step_edges;        // k: the edge of each step
  std::vector<bool> step_reversed;       // k: the edge points from v_i to v_{i-1}
  jet::Sim3<double> from_from_to;        // Z_1 ... Z_k
  Matrix7d sqrt_information;             // S with S^T S = Sigma^-1
};

struct ChainReduction {
  std::vector<bool> kept;            // per vertex index
  std::vector<size_t> direct_edges;  // edges whose both ends are kept
  std::vector<ReducedChain> chains;  // every other edge belongs to exactly one chain
  size_t num_kept = 0;
};

// `ends[e]` are the vertex indices {from, to} of edges[e]. `must_keep` (per vertex) marks loop ends
// and the gauge vertex; vertices with other than two edges, two edges to the same neighbour, or an
// edge whose information is not positive definite are kept too, and so is every
// `max_chain_length`-th vertex along a chain (and one vertex of a cycle of chain vertices).
ChainReduction ReduceChains(const std::vector<PoseGraphEdge>& edges,
                            const std::vector<std::array<size_t, 2>>& ends,
                            std::vector<bool> must_keep, int max_chain_length);

// Covariance Sigma_i of a chain step (the edge's inverse information, transported by Ad(Z) when
// the edge points against the chain).
Matrix7d StepCovariance(const PoseGraphEdge& edge, bool reversed);

// Writes the interior vertices of `chain` (parameter blocks in Sim3d::ToVector order) from the
// solved poses of its two ends. `edges` are the graph's edges (for the step covariances).
void RecoverInterior(const ReducedChain& chain, const std::vector<PoseGraphEdge>& edges,
                     const jet::Sim3<double>& world_from_first,
                     const jet::Sim3<double>& world_from_last, std::vector<Vector8d>* params);

}  // namespace sparseloop::internal
