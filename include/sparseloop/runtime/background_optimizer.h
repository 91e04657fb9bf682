#pragma once
// A thin threading shell around the synchronous PoseGraph::Optimize.
//
// The tracking thread pushes keyframes (raw poses) and loops into a bounded queue; a background
// thread owns the pose graph, applies the messages, and solves whenever new loops arrived. A loop
// pushed while a solve runs raises an atomic flag that a Ceres IterationCallback turns into
// SOLVER_TERMINATE_SUCCESSFULLY: the partial solution is kept as a warm start and the graph is
// re-solved with all loops. Every completed (non-interrupted) solve is delivered through the
// callback, on the background thread. No sleep-polling: condition variables only.
// With solve_while_running = false the graph is only built while the stream runs and solved once,
// by Finish() (the offline `run`: the same graph and the same solve as PoseGraph::Optimize on it).
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include "sparseloop/posegraph/pose_graph.h"

namespace sparseloop {

struct BackgroundOptimizerOptions {
  size_t queue_capacity = 256;  // messages; PushX blocks while the queue is full (backpressure)
  VertexType vertex_type = VertexType::kSim3;  // type of the graph the optimiser builds
  OdometryWeighting odometry;  // information of the odometry edges between pushed keyframes
  PoseGraphOptions solve;      // options of every solve
  // After each solve, return the heap the solve freed (its Ceres problem, Jacobians and
  // factorisation) to the operating system (glibc malloc_trim; no effect elsewhere). Without it
  // the background thread's malloc arena keeps the high-water mark of the largest solve so far,
  // which grows with the graph (docs/ROBUSTNESS.md, "Soak"). Costs well under a millisecond.
  bool release_memory_after_solve = true;
  // true: solve in the background whenever new loops arrived; false: no solve before Finish(),
  // which runs one solve over every loop (and no solve is ever interrupted).
  bool solve_while_running = true;
  void Check() const;
};

// One delivered correction.
struct PoseCorrection {
  uint64_t revision = 0;                   // 1, 2, ... in delivery order
  size_t num_loops = 0;                    // loops in the graph when this solve started
  std::vector<int64_t> ids;                // keyframe ids in insertion order
  std::vector<Sim3d> world_from_keyframe;  // corrected poses, same order
  PoseGraphSummary summary;
};

class BackgroundOptimizer {
 public:
  using Callback = std::function<void(const PoseCorrection&)>;

  // `callback` runs on the background thread; it must not call back into this object.
  BackgroundOptimizer(const BackgroundOptimizerOptions& options, Callback callback);
  ~BackgroundOptimizer();  // Finish()
  BackgroundOptimizer(const BackgroundOptimizer&) = delete;
  BackgroundOptimizer& operator=(const BackgroundOptimizer&) = delete;

  // Keyframes in time order; consecutive keyframes are joined by an odometry edge with the raw
  // relative pose. Returns false when the stream was already finished.
  // `odometry_information` (optional): the information of the odometry edge from the previous
  // keyframe to this one, instead of options.odometry's model.
  bool PushKeyframe(int64_t id, const Sim3d& raw_world_from_keyframe,
                    const std::optional<Matrix7d>& odometry_information = std::nullopt);
  // A loop between two keyframes already pushed. Interrupts a running solve.
  bool PushLoop(const LoopConstraint& loop);
  // End of stream: processes everything queued, runs the final solve if loops arrived since the
  // last completed one, joins the thread. Idempotent.
  void Finish();
  // Blocks until every message pushed so far is applied and no solve is running or due (the
  // callback of the last solve has returned). With solve_while_running = false only the queue is
  // drained. Returns at once after Finish(). Must not be called from the callback.
  void WaitForIdle();

  // The first failure of the background thread (a solve or a message that threw: it is caught,
  // logged, and no later solve runs), "" while there is none. Thread-safe.
  std::string failure() const;

  // Counters (for tests and logs).
  uint64_t num_solves() const { return num_solves_.load(); }
  uint64_t num_interrupted() const { return num_interrupted_.load(); }
  // The graph after Finish() (the background thread owns it before).
  const PoseGraph& graph() const;

 private:
  struct KeyframeMsg {
    int64_t id;
    Sim3d raw;
    std::optional<Matrix7d> information;  // of the odometry edge ending here; none: the model
  };
  struct EndMsg {};
  using Message = std::variant<KeyframeMsg, LoopConstraint, EndMsg>;

  bool Push(Message message);
  void Run();
  void Apply(const Message& message, bool* end, bool* new_loops);
  void Fail(const std::string& what);  // logs and records the first failure

  BackgroundOptimizerOptions options_;
  Callback callback_;
  PoseGraph graph_;
  bool has_last_raw_ = false;
  Sim3d last_raw_;
  int64_t last_id_ = 0;
  bool solved_ = false;  // a solve (even an interrupted one) has moved the graph's estimates

  mutable std::mutex mutex_;
  std::condition_variable not_empty_;
  std::condition_variable not_full_;
  std::condition_variable idle_cv_;
  bool working_ = true;  // the background thread is applying messages or solving
  std::deque<Message> queue_;
  bool closed_ = false;  // no more pushes accepted
  std::atomic<bool> interrupt_{false};
  std::atomic<uint64_t> num_solves_{0};
  std::atomic<uint64_t> num_interrupted_{0};
  uint64_t revision_ = 0;
  bool finished_ = false;
  std::string failure_;  // guarded by mutex_
  std::thread thread_;
};

}  // namespace sparseloop
