#include "pose_track.h"

#include <algorithm>
#include <cmath>

namespace sparseloop {

PoseReset PoseTrack::Classify(const std::optional<Sim3d>& pose_in, bool caller_reset) const {
  if (!pose_in || !last_pose_) return PoseReset::kNone;
  if (caller_reset) return PoseReset::kCaller;
  // The rules read the segment's motion: from 5 steps on (a handful of keyframes given far apart,
  // e.g. photos of one place with their poses, is not a vSLAM losing track).
  if (segment_steps_ < 5) return PoseReset::kNone;
  const Sim3d& pose = *pose_in;
  const Sim3d& last = *last_pose_;
  if (rules_.jump_max_scale > 0) {
    const double ratio = pose.scale / last.scale;
    if (ratio > rules_.jump_max_scale || ratio < 1.0 / rules_.jump_max_scale)
      return PoseReset::kScaleJump;
  }
  if (rules_.jump_max_deg > 0 &&
      last.rotation.angularDistance(pose.rotation) > rules_.jump_max_deg * M_PI / 180.0)
    return PoseReset::kRotationJump;
  if (rules_.jump_factor > 0) {
    std::vector<double> steps(recent_steps_.begin(), recent_steps_.end());
    const auto mid = steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2);
    std::nth_element(steps.begin(), mid, steps.end());
    // The mean keeps a long stop (steps near 0) from making the first step after it a "jump".
    const double usual = std::max(*mid, segment_path_ / segment_steps_);
    const double step = (pose.translation - last.translation).norm();
    if (usual > 0 && step > rules_.jump_factor * usual) return PoseReset::kTranslationJump;
  }
  return PoseReset::kNone;
}

double PoseTrack::Advance(const std::optional<Sim3d>& pose, PoseReset reset) {
  if (!pose) return 0.0;
  double step = 0.0;
  if (reset != PoseReset::kNone) {
    ++current_segment_;
    recent_steps_.clear();
    segment_path_ = 0.0;
    segment_steps_ = 0;
    step = last_step_;
  } else {
    if (last_pose_) {
      step = (pose->translation - last_pose_->translation).norm();
      recent_steps_.push_back(step);
      if (recent_steps_.size() > 20) recent_steps_.pop_front();
      segment_path_ += step;
      ++segment_steps_;
    }
    last_step_ = step;
  }
  last_pose_ = *pose;
  return step;
}

void PoseTrack::Store(const std::optional<Eigen::Vector3d>& position) {
  if (position) last_position_ = *position;
  segment_.push_back(current_segment_);
}

}  // namespace sparseloop
