#pragma once
// The raw pose track: the one place that knows the previous raw pose. It splits the raw
// trajectory into pose segments (a vSLAM that lost track and re-initialised starts a new world
// frame: KeyframeInput::pose_reset, or a jump the rules below notice), gives each stored keyframe
// its segment, and measures the raw step a loop's length is read against.
#include <cstddef>
#include <deque>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "sparseloop/core/sim3.h"
#include "sparseloop/loop/loop_detector.h"

namespace sparseloop {

class PoseTrack {
 public:
  // LoopDetectorOptions::pose_jump_*: a raw step this x the segment's usual one, a rotation step
  // above max_deg, a scale step beyond max_scale (0: that rule off).
  struct Rules {
    double jump_factor = 20.0;
    double jump_max_deg = 90.0;
    double jump_max_scale = 2.0;
  };
  explicit PoseTrack(Rules rules) : rules_(rules) {}

  // Why a keyframe with this raw pose (and the caller's reset flag) starts a new segment; kNone
  // without a pose or before the first one. Changes nothing.
  PoseReset Classify(const std::optional<Sim3d>& pose, bool caller_reset) const;

  // The keyframe is taken: a new segment when `reset` is not kNone; with a pose, the step from
  // the previous pose joins the segment's statistics. Returns the raw step at this keyframe: the
  // distance from the previous raw pose, the last step before it across a reset, 0 for the first
  // pose or without one.
  double Advance(const std::optional<Sim3d>& pose, PoseReset reset);

  // The stored keyframe at the next index: its segment, and its place (a keyframe without a
  // pose stays where the last posed one was).
  void Store(const std::optional<Eigen::Vector3d>& position);

  int current_segment() const { return current_segment_; }
  bool SameSegment(size_t a, size_t b) const { return segment_[a] == segment_[b]; }
  const Eigen::Vector3d& last_position() const { return last_position_; }

 private:
  Rules rules_;
  std::vector<int> segment_;  // of each stored keyframe
  int current_segment_ = 0;
  std::optional<Sim3d> last_pose_;
  std::deque<double> recent_steps_;  // the segment's last steps, at most 20
  double segment_path_ = 0.0;
  int segment_steps_ = 0;
  double last_step_ = 0.0;  // the step a keyframe across a reset stands in with
  Eigen::Vector3d last_position_ = Eigen::Vector3d::Zero();
};

}  // namespace sparseloop
