#include "sparseloop/runtime/loop_closing.h"

#include <algorithm>
#include <stdexcept>

#include <fmt/format.h>

#include "sparseloop/core/check.h"
#include "sparseloop/core/error.h"
#include "sparseloop/core/logging.h"

namespace sparseloop {

void LoopClosing::Options::Check() const {
  detector.Check();
  loop_edge.Check();
  optimizer.Check();
}

LoopClosing::LoopClosing(Options options, CorrectionCallback on_correction)
    : options_((options.Check(), std::move(options))),
      on_correction_(std::move(on_correction)),
      detector_(options_.detector) {
  if (options_.optimize) {
    optimizer_ = std::make_unique<BackgroundOptimizer>(
        options_.optimizer, [this](const PoseCorrection& c) { OnCorrection(c); });
  }
}

LoopClosing::~LoopClosing() {
  try {
    Finish();
  } catch (const std::exception&) {
    // Already logged by the optimizer thread; a destructor must not throw.
  }
}

void LoopClosing::AddPriorKeyframes(int64_t session, std::vector<KeyframeRecord> records) {
  std::lock_guard<std::mutex> api_lock(api_mutex_);
  SL_CHECK_MSG(!finished_, "AddPriorKeyframes after Finish(): the loop closer is closed");
  detector_.AddPriorKeyframes(session, std::move(records));
}

LoopEvent LoopClosing::AddKeyframe(const KeyframeInput& keyframe) {
  std::lock_guard<std::mutex> api_lock(api_mutex_);
  SL_CHECK_MSG(!finished_, "AddKeyframe({}) after Finish(): the loop closer is closed",
               keyframe.id);
  SL_CHECK_MSG(!has_last_id_ || keyframe.id > last_id_,
               "keyframe id {} must be greater than the previous keyframe's ({})", keyframe.id,
               last_id_);
  // The caller's odometry covariance is checked first: a bad one changes nothing.
  std::optional<Matrix7d> odometry_information;
  if (keyframe.odometry_covariance && optimizer_ && keyframe.world_from_cam) {
    try {
      odometry_information =
          options_.optimizer.odometry.InformationFromCovariance(*keyframe.odometry_covariance);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(fmt::format("keyframe {}: KeyframeInput::odometry_covariance: {}",
                                              keyframe.id, e.what()));
    }
  }
  // Validates everything else before any state changes (throws with the detector unchanged).
  LoopEvent event;
  event.result = detector_.Process(keyframe);
  if (event.result.pose_reset != PoseReset::kNone) {
    // The raw step across a pose reset (KeyframeInput::pose_reset, or a jump the detector
    // noticed) measures nothing: an edge of sigma 1,000 (raw units, rad, log-scale) only holds
    // the new segment's gauge, so neither segment bends towards the jump. Metric relocalisations
    // into an earlier segment (below) then bring the new segment into the earlier one's frame.
    odometry_information = Matrix7d::Identity() * 1e-6;
  }
  has_last_id_ = true;
  last_id_ = keyframe.id;
  ++num_keyframes_;
  if (!optimizer_ || !keyframe.world_from_cam) return event;

  const Sim3d& raw = *keyframe.world_from_cam;
  {
    std::lock_guard<std::mutex> lock(poses_mutex_);
    unsolved_ids_.push_back(keyframe.id);
    unsolved_raw_.push_back(raw);
  }
  // Blocks while the queue is full. The first graph keyframe has no odometry edge: its
  // covariance, if any, is not used.
  optimizer_->PushKeyframe(keyframe.id, raw, odometry_information);
  event.in_graph = true;
  // Local step length at the query: from the previous graph keyframe, which is the detector's
  // previous keyframe with a pose (across a raw pose reset the last step before it stands in).
  const double local_step = event.result.raw_step;

  const LoopResult& r = event.result;
  // A relocalisation into an earlier raw pose segment of this session is a loop edge when its
  // pose is metric (PnP / Sim(3)): it does not read the raw poses of the two ends, which are in
  // different frames. A two-view (direction) loop takes its length from the raw step and the
  // match's raw scale, which a re-initialised monocular vSLAM changes: it stays out.
  const bool across_reset =
      r.detected() && r.source == CandidateSource::kEarlierSegment &&
      (r.pose_kind == RelativePoseKind::kSim3 || r.pose_kind == RelativePoseKind::kSE3Metric);
  if (!r.detected() || r.match_session != 0 || (r.relocalization && !across_reset)) return event;
  const KeyframeRecord& match = detector_.record(r.match_id);
  if (!match.has_pose) return event;  // no graph vertex (a global-search match without pose)
  LoopConstraint edge;
  try {
    edge = MakeLoopConstraint(r, raw, match.world_from_cam, local_step, options_.loop_edge);
  } catch (const std::invalid_argument& e) {
    Logger().warn("loop closing: loop {} -> {} not sent to the optimizer: {}", r.query_id,
                  r.match_id, e.what());
    return event;
  }
  event.loop_information = LoopEffectiveInformation(edge);
  optimizer_->PushLoop(edge);
  event.loop_in_graph = true;
  event.loop_index = static_cast<int64_t>(num_loops_++);
  return event;
}

void LoopClosing::Finish() {
  std::lock_guard<std::mutex> api_lock(api_mutex_);
  if (finished_) return;
  if (optimizer_) optimizer_->Finish();
  finished_ = true;
  ThrowIfOptimizerFailed();
}

void LoopClosing::ThrowIfOptimizerFailed() const {
  const std::string failure = optimizer_ ? optimizer_->failure() : std::string();
  if (!failure.empty())
    throw Error(
        fmt::format("pose graph optimisation failed: {} (corrections are those of the last "
                    "solve before it)",
                    failure));
}

bool LoopClosing::finished() const { return finished_; }

void LoopClosing::WaitForIdle() {
  std::lock_guard<std::mutex> api_lock(api_mutex_);
  if (optimizer_ && !finished_) optimizer_->WaitForIdle();
  ThrowIfOptimizerFailed();
}

void LoopClosing::OnCorrection(const PoseCorrection& correction) {
  auto copy = std::make_shared<const PoseCorrection>(correction);
  {
    std::lock_guard<std::mutex> lock(poses_mutex_);
    if (!copy->ids.empty()) {
      // Keyframes up to the solve's last one are solved now; keep the raw pose of that last one
      // (the anchor of the extrapolation), drop the others.
      const int64_t last = copy->ids.back();
      const auto end = std::upper_bound(unsolved_ids_.begin(), unsolved_ids_.end(), last);
      const size_t n = static_cast<size_t>(end - unsolved_ids_.begin());
      if (n > 0 && unsolved_ids_[n - 1] == last) last_solved_raw_ = unsolved_raw_[n - 1];
      unsolved_ids_.erase(unsolved_ids_.begin(), end);
      unsolved_raw_.erase(unsolved_raw_.begin(), unsolved_raw_.begin() + static_cast<long>(n));
    }
    latest_ = copy;
  }
  if (on_correction_) on_correction_(*copy);
}

CorrectedKeyframes LoopClosing::Corrections() const {
  std::lock_guard<std::mutex> lock(poses_mutex_);
  CorrectedKeyframes out;
  Sim3d correction;  // corrected(last solved) * raw(last solved)^-1; identity before any solve
  if (latest_) {
    out.revision = latest_->revision;
    out.ids = latest_->ids;
    out.world_from_keyframe = latest_->world_from_keyframe;
    out.num_solved = out.ids.size();
    if (!out.ids.empty())
      correction = latest_->world_from_keyframe.back() * last_solved_raw_.Inverse();
  }
  out.ids.insert(out.ids.end(), unsolved_ids_.begin(), unsolved_ids_.end());
  for (const Sim3d& raw : unsolved_raw_) out.world_from_keyframe.push_back(correction * raw);
  return out;
}

std::optional<KeyframeCorrection> LoopClosing::CorrectedPose(int64_t id) const {
  std::lock_guard<std::mutex> lock(poses_mutex_);
  KeyframeCorrection out;
  Sim3d correction;
  if (latest_) {
    out.revision = latest_->revision;
    const auto& ids = latest_->ids;
    const auto it = std::lower_bound(ids.begin(), ids.end(), id);
    if (it != ids.end() && *it == id) {
      out.world_from_keyframe = latest_->world_from_keyframe[static_cast<size_t>(it - ids.begin())];
      out.solved = true;
      return out;
    }
    if (!ids.empty()) correction = latest_->world_from_keyframe.back() * last_solved_raw_.Inverse();
  }
  const auto it = std::lower_bound(unsolved_ids_.begin(), unsolved_ids_.end(), id);
  if (it == unsolved_ids_.end() || *it != id) return std::nullopt;
  out.world_from_keyframe =
      correction * unsolved_raw_[static_cast<size_t>(it - unsolved_ids_.begin())];
  return out;
}

std::shared_ptr<const PoseCorrection> LoopClosing::LatestSolve() const {
  std::lock_guard<std::mutex> lock(poses_mutex_);
  return latest_;
}

size_t LoopClosing::num_keyframes() const { return num_keyframes_; }
size_t LoopClosing::num_loops() const { return num_loops_; }
uint64_t LoopClosing::num_solves() const { return optimizer_ ? optimizer_->num_solves() : 0; }

uint64_t LoopClosing::num_interrupted_solves() const {
  return optimizer_ ? optimizer_->num_interrupted() : 0;
}

const PoseGraph& LoopClosing::graph() const {
  SL_CHECK_MSG(optimizer_ != nullptr, "graph(): LoopClosing runs without optimize");
  SL_CHECK_MSG(finished_, "graph() is only available after Finish()");
  return optimizer_->graph();
}

}  // namespace sparseloop
