#pragma once
// The online loop closer: what a vSLAM constructs. Push keyframes as tracking makes them; each
// AddKeyframe runs loop detection synchronously on the caller's thread and returns the loop
// event; the keyframe (raw pose) and every detected loop edge go to a BackgroundOptimizer, whose
// thread solves the Sim(3) pose graph (PCM outlier rejection) while tracking goes on. Corrected
// poses come back through a callback (on the background thread) and can be polled from any thread.
//
//   LoopClosing closing(options, [](const PoseCorrection& c) { /* background thread */ });
//   LoopEvent e = closing.AddKeyframe(keyframe);   // tracking thread
//   if (e.result.detected()) ...                   // e.result.match_id, e.result.match_from_query
//   std::optional<KeyframeCorrection> p = closing.CorrectedPose(id);  // any thread
//   closing.Finish();                              // final solve; closing.Corrections()
//
// Threading: AddKeyframe, Finish and WaitForIdle are serialised by an internal mutex (call them
// from the tracking thread; another thread calling them waits its turn). Corrections,
// CorrectedPose, LatestSolve and the counters are safe from any thread, the callback included.
// AddKeyframe blocks while the optimiser's queue is full (Options::optimizer.queue_capacity):
// the backpressure of a background solve that cannot keep up.
//
// Keyframes without a raw pose (KeyframeInput::world_from_cam empty: tracking lost) go to the
// detector only, which relocalises them or searches globally (LoopDetector::Process); they get no
// graph vertex and no loop edge, and CorrectedPose(id) is empty for them. The odometry chain of
// the graph joins the keyframes WITH poses in order. Raw poses that continue in a new world frame
// after the gap (the vSLAM re-initialised) must be flagged KeyframeInput::pose_reset (or the
// detector must notice the jump): the odometry edge across the reset then has no weight, and
// metric relocalisations into the earlier segment become loop edges that bring the new segment
// into the earlier one's frame (docs/MULTISESSION.md, "Raw pose resets").
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "sparseloop/loop/loop_detector.h"
#include "sparseloop/runtime/background_optimizer.h"
#include "sparseloop/runtime/loop_edge.h"

namespace sparseloop {

// What AddKeyframe returns.
struct LoopEvent {
  LoopResult result;      // the detector's verdict for this keyframe (status, match, relative pose)
  bool in_graph = false;  // the keyframe became a pose-graph vertex (it has a pose; optimize on)
  // The loop went to the optimiser as a loop edge: detected, match in this session (not a prior
  // map session), both keyframes in the graph, and not a relocalisation, except a metric one
  // into an earlier raw pose segment (LoopResult::source kEarlierSegment).
  bool loop_in_graph = false;
  // With loop_in_graph: index of the loop in the graph's loop list, the index that
  // PoseGraphSummary::rejected_loops (PCM) refers to; -1 otherwise.
  int64_t loop_index = -1;
  // With loop_in_graph: the information of the loop edge as the graph weighs it
  // (LoopEffectiveInformation: the estimate's, inflated, with the floors), in the tangent order
  // [upsilon, omega, sigma] of a right perturbation of match_from_query; for checking it against
  // the exact relative pose (eval/loop_nees.h).
  Matrix7d loop_information = Matrix7d::Zero();
};

// The corrected pose of one keyframe (CorrectedPose).
struct KeyframeCorrection {
  Sim3d world_from_keyframe;  // corrected pose, world frame of the raw poses
  uint64_t revision = 0;      // the solve it comes from (PoseCorrection::revision); 0: none yet
  // true: the solve estimated this keyframe; false: it was added after that solve (or before any
  // solve) and its pose is the last correction composed onto its raw pose:
  // corrected(last solved) * raw(last solved)^-1 * raw(this) (the raw pose while revision is 0).
  bool solved = false;
};

// Every graph keyframe so far, corrected (Corrections).
struct CorrectedKeyframes {
  uint64_t revision = 0;                   // the solve these come from; 0: none yet (raw poses)
  std::vector<int64_t> ids;                // graph keyframes, in insertion order
  std::vector<Sim3d> world_from_keyframe;  // same order; as KeyframeCorrection
  size_t num_solved = 0;  // the first num_solved entries are the solve's; the rest extrapolated
};

class LoopClosing {
 public:
  struct Options {
    LoopDetector::Options detector;
    LoopEdgeOptions loop_edge;  // how a detected loop becomes a loop edge (as `run` does it)
    // The background optimiser: queue capacity (backpressure), vertex type, odometry weighting,
    // the solve's options (PCM rejection, ...), and solve_while_running (false: one solve, by
    // Finish(), over every loop: what `run` computes).
    BackgroundOptimizerOptions optimizer;
    // false: detection only (loop events; no pose graph, no background thread, no corrections).
    bool optimize = true;
    void Check() const;
  };
  using CorrectionCallback = std::function<void(const PoseCorrection&)>;

  // Throws std::invalid_argument when the options are invalid. `on_correction` (optional) runs
  // on the background thread after each completed solve, once LoopClosing's own copy is updated
  // (so it may poll Corrections / CorrectedPose); it must not call AddKeyframe, Finish or
  // WaitForIdle, and should return quickly (the next solve waits for it).
  explicit LoopClosing(Options options, CorrectionCallback on_correction = {});
  ~LoopClosing();  // Finish()
  LoopClosing(const LoopClosing&) = delete;
  LoopClosing& operator=(const LoopClosing&) = delete;

  // Multi-session: the keyframes of an earlier map session (LoopDetector::AddPriorKeyframes),
  // searched by appearance for cross-session loops and relocalisation. They get no graph vertex
  // (their world frame differs) and a loop into them no loop edge. Throws std::invalid_argument
  // (nothing added) on a bad session or record, and after Finish().
  void AddPriorKeyframes(int64_t session, std::vector<KeyframeRecord> records);

  // Detects a loop for the keyframe, then queues the keyframe and its loop edge for the
  // background solve. Keyframe ids must increase strictly; timestamps, image and pose are
  // checked by LoopDetector::Process. Throws std::invalid_argument on bad input (nothing stored:
  // the detector, the graph and the corrections are as before) and after Finish().
  LoopEvent AddKeyframe(const KeyframeInput& keyframe);

  // End of stream: queued keyframes and loops are applied, the final solve runs if loops arrived
  // since the last completed one (its correction is delivered as any other), the background
  // thread is joined. Idempotent; the destructor calls it. Throws sparseloop::Error when a solve
  // failed in the background thread (logged there; nothing is solved after it).
  void Finish();
  bool finished() const;

  // Blocks until every keyframe and loop added so far is in the graph and no solve is running or
  // due (corrections of every solve delivered). For tests and for a caller that wants the
  // freshest correction now; with optimizer.solve_while_running = false nothing is solved before
  // Finish(). Returns at once after Finish() or without optimize. Throws sparseloop::Error as
  // Finish() does.
  void WaitForIdle();

  // Thread-safe polls of the latest completed solve.
  // Every graph keyframe so far (see CorrectedKeyframes); raw poses before the first solve.
  CorrectedKeyframes Corrections() const;
  // One keyframe; empty for an id never added or added without a pose (no graph vertex).
  std::optional<KeyframeCorrection> CorrectedPose(int64_t id) const;
  // The latest solve as delivered (graph keyframes at that solve, summary with PCM's rejected
  // loops); nullptr before the first completed solve.
  std::shared_ptr<const PoseCorrection> LatestSolve() const;

  const Options& options() const { return options_; }
  // The detector: read it only from the thread that calls AddKeyframe (it is not locked).
  const LoopDetector& detector() const { return detector_; }
  size_t num_keyframes() const;  // keyframes accepted by AddKeyframe
  size_t num_loops() const;      // loop edges sent to the optimiser
  uint64_t num_solves() const;   // solves run so far (BackgroundOptimizer::num_solves; 0 without)
  // Of those, the ones a newer loop interrupted (re-solved at once; no callback, no new revision).
  uint64_t num_interrupted_solves() const;
  // The optimiser's graph, after Finish() with optimize (throws std::invalid_argument otherwise).
  const PoseGraph& graph() const;

 private:
  void OnCorrection(const PoseCorrection& correction);
  void ThrowIfOptimizerFailed() const;  // sparseloop::Error with the optimizer's failure

  Options options_;
  CorrectionCallback on_correction_;
  LoopDetector detector_;

  // Caller-thread state, guarded by api_mutex_ (the atomics are also read without it).
  std::mutex api_mutex_;
  bool has_last_id_ = false;
  int64_t last_id_ = 0;
  std::atomic<bool> finished_{false};
  std::atomic<size_t> num_keyframes_{0};
  std::atomic<size_t> num_loops_{0};

  // Corrections, guarded by poses_mutex_ (written by both threads, read by any).
  mutable std::mutex poses_mutex_;
  std::shared_ptr<const PoseCorrection> latest_;
  // Graph keyframes newer than the last keyframe of latest_ (all of them before the first solve):
  // ids increasing, raw poses. Older raw poses are not kept: the solve replaced them.
  std::vector<int64_t> unsolved_ids_;
  std::vector<Sim3d> unsolved_raw_;
  Sim3d last_solved_raw_;  // raw pose of latest_'s last keyframe

  std::unique_ptr<BackgroundOptimizer> optimizer_;  // last member: its thread stops first
};

}  // namespace sparseloop
