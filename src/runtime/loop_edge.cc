#include "sparseloop/runtime/loop_edge.h"

#include <algorithm>

#include "sparseloop/core/check.h"

namespace sparseloop {

void LoopEdgeOptions::Check() const {
  direction_loop.Check();
  SL_CHECK_MSG(loop_translation_sigma_steps > 0, "loop_translation_sigma_steps must be > 0");
  SL_CHECK_MSG(loop_rotation_sigma_rad > 0, "loop_rotation_sigma_rad must be > 0");
  SL_CHECK_MSG(loop_scale_sigma > 0, "loop_scale_sigma must be > 0");
  SL_CHECK_MSG(loop_covariance_inflation >= 1, "loop_covariance_inflation must be >= 1, got {}",
               loop_covariance_inflation);
  SL_CHECK_MSG(loop_min_translation_sigma_steps > 0 && loop_min_rotation_sigma_rad > 0 &&
                   loop_min_scale_sigma > 0,
               "loop_min_translation_sigma_steps, loop_min_rotation_sigma_rad and "
               "loop_min_scale_sigma must be > 0");
}

LoopConstraint MakeLoopConstraint(const LoopResult& loop, const Sim3d& raw_world_from_query,
                                  const Sim3d& raw_world_from_match, double local_step_length,
                                  const LoopEdgeOptions& options) {
  const double weight = std::clamp(loop.score, 0.1, 1.0);
  if (loop.pose_kind == RelativePoseKind::kSE3UnitTranslation) {
    DirectionLoopOptions dir = options.direction_loop;
    dir.weight *= weight;
    return MakeLoopConstraintFromDirection(loop.query_id, loop.match_id, raw_world_from_query,
                                           raw_world_from_match, loop.match_from_query.rotation,
                                           loop.match_from_query.translation.normalized(),
                                           local_step_length, dir);
  }
  SL_CHECK_MSG(
      loop.pose_kind == RelativePoseKind::kSim3 || loop.pose_kind == RelativePoseKind::kSE3Metric,
      "loop {} -> {} carries no relative pose", loop.query_id, loop.match_id);
  LoopConstraint c;
  c.query_id = loop.query_id;
  c.match_id = loop.match_id;
  c.match_from_query = loop.match_from_query;
  c.has_scale = loop.pose_kind == RelativePoseKind::kSim3;
  if (options.loop_information_from_estimate && loop.information.trace() > 0 &&
      loop.information.allFinite()) {
    // Omega' (I + F Omega')^-1 = (Omega'^-1 + F)^-1 where Omega' is invertible; keeps the null
    // space of a rank-deficient Omega' (PnP: the relative scale) instead of inventing information.
    const Matrix7d omega = loop.information / options.loop_covariance_inflation;
    const double ft = std::max(options.loop_min_translation_sigma_steps * local_step_length, 1e-6);
    const double fr = options.loop_min_rotation_sigma_rad;
    const double fs = options.loop_min_scale_sigma;
    Vector7d floor2;
    floor2 << ft * ft, ft * ft, ft * ft, fr * fr, fr * fr, fr * fr, fs * fs;
    const Matrix7d capped = omega * (Matrix7d::Identity() + floor2.asDiagonal() * omega).inverse();
    c.information = 0.5 * (capped + capped.transpose());
    c.weight = 1.0;
    return c;
  }
  c.information =
      LoopInformation(std::max(options.loop_translation_sigma_steps * local_step_length, 1e-6),
                      options.loop_rotation_sigma_rad, options.loop_scale_sigma);
  if (!c.has_scale) c.information(6, 6) = 0.0;
  c.weight = weight;
  return c;
}

}  // namespace sparseloop
