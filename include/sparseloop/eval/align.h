#pragma once
// Closed-form least-squares alignment of two corresponding point sets (Umeyama 1991, "Least-squares
// estimation of transformation parameters between two point patterns", PAMI 13(4)).
//
// Given est points x_i and gt points y_i (same count, corresponding by index), Umeyama finds the
// transform gt_from_est = (s, R, t) minimising sum_i |y_i - (s R x_i + t)|^2:
//   mu_x, mu_y   means;  sigma_x^2 = 1/n sum |x_i - mu_x|^2
//   Sigma_xy     = 1/n sum (y_i - mu_y)(x_i - mu_x)^T = U D V^T (SVD)
//   S            = I, or diag(1, 1, -1) when det(U) det(V) < 0 (no reflections)
//   R = U S V^T,  s = trace(D S) / sigma_x^2 (Sim3 only, else 1),  t = mu_y - s R mu_x.
// This is what evo (`evo_ape -a` / `-as`) computes.
//
// Degenerate inputs (documented behaviour, never an exception for data):
//  - kNone: always kOk with the identity transform.
//  - fewer than 3 points: status kTooFewPoints, identity transform.
//  - all est points identical (sigma_x == 0) or all gt points identical: status kDegenerate,
//    R = I, s = 1, t = mu_y - mu_x (a pure translation, which is still a least-squares minimiser
//    for SE(3); for Sim(3) the scale is unobservable).
//  - collinear points (second singular value of Sigma_xy below 1e-9 times the first): status
//    kDegenerate, but the transform returned is still a least-squares minimiser: the rotation about
//    the line is arbitrary, so point errors (ATE) are well defined while anything depending on the
//    full rotation (RPE / KITTI on full poses after Sim3/SE3 alignment) is not meaningful.
// Mismatched sizes are a caller bug: std::invalid_argument.
#include <string>
#include <vector>

#include <Eigen/Core>

#include "sparseloop/core/sim3.h"

namespace sparseloop {

enum class Alignment { kNone, kSE3, kSim3 };

// "none", "se3", "sim3" (case-sensitive); anything else throws std::invalid_argument.
Alignment ParseAlignment(const std::string& name);
std::string ToString(Alignment alignment);

enum class AlignmentStatus {
  kOk,            // unique least-squares transform
  kTooFewPoints,  // fewer than 3 correspondences: identity returned
  kDegenerate,    // a minimiser was returned but it is not unique (see header comment)
};
std::string ToString(AlignmentStatus status);

struct AlignmentResult {
  AlignmentStatus status = AlignmentStatus::kOk;
  Alignment type = Alignment::kNone;
  Sim3d gt_from_est;          // maps estimate points into the gt frame (scale 1 unless kSim3)
  size_t num_points = 0;      // correspondences used
  double rms_residual = 0.0;  // sqrt(1/n sum |y_i - T x_i|^2), gt units
};

// est[i] corresponds to gt[i]. Throws std::invalid_argument when est.size() != gt.size().
AlignmentResult Umeyama(const std::vector<Eigen::Vector3d>& est,
                        const std::vector<Eigen::Vector3d>& gt, Alignment type);

}  // namespace sparseloop
