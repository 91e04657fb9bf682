#include "sparseloop/posegraph/interpolation.h"

#include <algorithm>
#include <cmath>

#include "sparseloop/core/check.h"

namespace sparseloop {

Sim3d InterpolateSim3(const Sim3d& a, const Sim3d& b, double alpha) {
  SL_CHECK_MSG(std::isfinite(alpha), "alpha must be finite");
  const Vector7d d = (a.Inverse() * b).Log();
  return a * Sim3d::Exp(alpha * d);
}

std::vector<StampedSim3> CorrectFramePoses(const std::vector<StampedSim3>& raw_keyframes,
                                           const std::vector<StampedSim3>& corrected_keyframes,
                                           const std::vector<StampedSim3>& raw_frames) {
  SL_CHECK_MSG(raw_keyframes.size() == corrected_keyframes.size(),
               "raw ({}) and corrected ({}) keyframes differ in size", raw_keyframes.size(),
               corrected_keyframes.size());
  SL_CHECK_MSG(!raw_keyframes.empty() || raw_frames.empty(), "no keyframes to interpolate from");
  std::vector<double> times(raw_keyframes.size());
  std::vector<Sim3d> deltas(raw_keyframes.size());
  for (size_t k = 0; k < raw_keyframes.size(); ++k) {
    SL_CHECK_MSG(raw_keyframes[k].timestamp == corrected_keyframes[k].timestamp,
                 "keyframe {} has different raw and corrected timestamps", k);
    SL_CHECK_MSG(k == 0 || raw_keyframes[k].timestamp > raw_keyframes[k - 1].timestamp,
                 "keyframe timestamps must increase (index {})", k);
    times[k] = raw_keyframes[k].timestamp;
    deltas[k] = corrected_keyframes[k].world_from_cam * raw_keyframes[k].world_from_cam.Inverse();
  }
  std::vector<StampedSim3> out;
  out.reserve(raw_frames.size());
  for (const StampedSim3& frame : raw_frames) {
    const double t = frame.timestamp;
    const auto it = std::upper_bound(times.begin(), times.end(), t);
    Sim3d delta;
    if (it == times.begin()) {
      delta = deltas.front();
    } else if (it == times.end()) {
      delta = deltas.back();
    } else {
      const size_t k1 = static_cast<size_t>(it - times.begin());
      const size_t k0 = k1 - 1;
      const double alpha = (t - times[k0]) / (times[k1] - times[k0]);
      delta = InterpolateSim3(deltas[k0], deltas[k1], alpha);
    }
    out.push_back({t, delta * frame.world_from_cam});
  }
  return out;
}

}  // namespace sparseloop
