#pragma once
// The pose-graph edge for a detected loop: one definition shared by the online LoopClosing
// (runtime/loop_closing.h) and the offline RunPipeline (pipeline/pipeline.h).
#include "sparseloop/loop/loop_detector.h"
#include "sparseloop/posegraph/pose_graph.h"

namespace sparseloop {

// How a detected loop becomes a loop edge (docs/POSEGRAPH.md, "Loop information"). The field
// names are the configuration keys (pipeline/config.h: PipelineOptions inherits this struct, so
// the keys sit at the top level of the JSON configuration).
struct LoopEdgeOptions {
  DirectionLoopOptions direction_loop;  // loops measured as rotation + unit direction (no depth)
  // Loops with a metric or Sim(3) relative pose (depths available): standard deviations.
  double loop_translation_sigma_steps = 0.5;  // in units of the raw step length at the query
  // rad; as DirectionLoopOptions::rotation_sigma_rad: a PnP / Sim(3) rotation is no less accurate
  // than a two-view one (castle 29 -> 02 from the local map: 0.16 deg).
  double loop_rotation_sigma_rad = 0.01;
  double loop_scale_sigma = 0.05;  // log-scale
  // Loops whose verification measured their own uncertainty (LoopResult::information: PnP and
  // Sim(3) loops) use it instead of the fixed sigmas above (docs/POSEGRAPH.md, "Loop
  // information"): covariance = inflation x the Gauss-Newton covariance of the inliers, plus the
  // floors below (added as covariances, so a loop never claims less than them), weight 1.
  bool loop_information_from_estimate = true;
  // Variance multiplier (>= 1): the inliers' Gauss-Newton covariance ignores the noise of the
  // local map the query was verified against (triangulated with raw relative poses) and the
  // correlation between neighbouring features. Measured in docs/POSEGRAPH.md (normalised
  // estimation error squared of castle and rendered loops against their ground truth).
  double loop_covariance_inflation = 10.0;
  double loop_min_translation_sigma_steps = 0.02;  // floor, in raw steps at the query
  double loop_min_rotation_sigma_rad = 0.001;      // floor, rad
  double loop_min_scale_sigma = 0.005;             // floor, log-scale
  void Check() const;
};

// The loop edge for a detected loop, chosen by what the detector measured (docs/POSEGRAPH.md):
// Sim(3) or metric SE(3) -> the full relative pose; rotation + unit direction -> the magnitude
// from the raw trajectory's local step length (distance between the raw positions of the query
// and the keyframe before it, raw units). Throws std::invalid_argument when the loop carries no
// relative pose.
LoopConstraint MakeLoopConstraint(const LoopResult& loop, const Sim3d& raw_world_from_query,
                                  const Sim3d& raw_world_from_match, double local_step_length,
                                  const LoopEdgeOptions& options);

}  // namespace sparseloop
