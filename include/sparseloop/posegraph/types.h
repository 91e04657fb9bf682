#pragma once
// The pose graph's public vocabulary, without Ceres: the vertex types and the 7x7 information
// of an edge. The Ceres cost functions and manifolds that implement them are internal
// (src/posegraph/edge_error.h, manifolds.h, sim3_jet.h).
#include <Eigen/Core>

namespace sparseloop {

// Information (inverse covariance) of an edge in tangent order [upsilon(3), omega(3), sigma].
using Matrix7d = Eigen::Matrix<double, 7, 7>;

enum class VertexType {
  kSim3,     // 7 DoF similarity (monocular: scale drifts)
  kSe3,      // 6 DoF rigid (stereo / RGB-D / VIO): scale kept as stored (1)
  kFourDof,  // x, y, z, yaw (gravity-aligned VIO: roll and pitch are observable)
  kSe2,      // x, y, yaw (planar 2D graphs)
};

// "sim3", "se3", "4dof", "se2" (the config key vertex_type and the CLI use these names).
const char* ToString(VertexType type);

// Tangent dimension of a vertex type (7, 6, 4, 3).
int TangentSize(VertexType type);

// S with S^T S = information for a symmetric positive semi-definite 7x7 matrix (eigen
// decomposition, so rank-deficient information such as 2D edges embedded in 7D is allowed).
// Throws std::invalid_argument for a non-symmetric or indefinite matrix.
Matrix7d SqrtInformation(const Matrix7d& information);

}  // namespace sparseloop
