#pragma once
// Correcting non-keyframe poses after a pose-graph solve.
//
// Each keyframe k gets a correction delta D_k = corrected_k * inv(raw_k) (corrected world from
// raw world). A frame at time t between keyframes k and k+1 gets
//   D(t) = D_k * exp(alpha * log(inv(D_k) * D_{k+1})),  alpha = (t - t_k) / (t_{k+1} - t_k),
// interpolated on the Sim(3) manifold, and its corrected pose is D(t) * raw(t). Frames before the
// first or after the last keyframe take the nearest keyframe's delta.
#include <vector>

#include "sparseloop/core/sim3.h"

namespace sparseloop {

struct StampedSim3 {
  double timestamp = 0.0;  // seconds (or frame index), strictly increasing for keyframes
  Sim3d world_from_cam;
};

// Interpolates a Sim(3) between a (alpha = 0) and b (alpha = 1) on the manifold.
Sim3d InterpolateSim3(const Sim3d& a, const Sim3d& b, double alpha);

// raw_keyframes and corrected_keyframes: same size, same timestamps, increasing in time.
// Returns the corrected poses of raw_frames (any order), same size and timestamps.
std::vector<StampedSim3> CorrectFramePoses(const std::vector<StampedSim3>& raw_keyframes,
                                           const std::vector<StampedSim3>& corrected_keyframes,
                                           const std::vector<StampedSim3>& raw_frames);

}  // namespace sparseloop
