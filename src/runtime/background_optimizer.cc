#include "sparseloop/runtime/background_optimizer.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "sparseloop/core/check.h"
#include "sparseloop/core/logging.h"

namespace sparseloop {

void BackgroundOptimizerOptions::Check() const {
  SL_CHECK_MSG(queue_capacity >= 1, "queue_capacity must be >= 1, got {}", queue_capacity);
  odometry.Check();
  solve.Check();
}

BackgroundOptimizer::BackgroundOptimizer(const BackgroundOptimizerOptions& options,
                                         Callback callback)
    : options_(options), callback_(std::move(callback)), graph_(options.vertex_type) {
  options_.Check();
  thread_ = std::thread([this] { Run(); });
}

BackgroundOptimizer::~BackgroundOptimizer() { Finish(); }

bool BackgroundOptimizer::Push(Message message) {
  std::unique_lock<std::mutex> lock(mutex_);
  not_full_.wait(lock, [&] { return closed_ || queue_.size() < options_.queue_capacity; });
  if (closed_) return false;
  const bool is_loop = std::holds_alternative<LoopConstraint>(message);
  const bool is_end = std::holds_alternative<EndMsg>(message);
  queue_.push_back(std::move(message));
  if (is_end) closed_ = true;
  // A newer loop makes the running solve obsolete: ask it to stop.
  if (is_loop) interrupt_.store(true, std::memory_order_release);
  lock.unlock();
  not_empty_.notify_one();
  return true;
}

bool BackgroundOptimizer::PushKeyframe(int64_t id, const Sim3d& raw_world_from_keyframe,
                                       const std::optional<Matrix7d>& odometry_information) {
  return Push(KeyframeMsg{id, raw_world_from_keyframe, odometry_information});
}

bool BackgroundOptimizer::PushLoop(const LoopConstraint& loop) { return Push(loop); }

void BackgroundOptimizer::Finish() {
  if (finished_) return;
  Push(EndMsg{});
  if (thread_.joinable()) thread_.join();
  finished_ = true;
}

const PoseGraph& BackgroundOptimizer::graph() const {
  SL_CHECK_MSG(finished_, "graph() is only available after Finish()");
  return graph_;
}

void BackgroundOptimizer::Apply(const Message& message, bool* end, bool* new_loops) {
  if (const auto* kf = std::get_if<KeyframeMsg>(&message)) {
    if (!has_last_raw_) {
      graph_.AddVertex(kf->id, kf->raw, kf->raw);
    } else {
      // Initial estimate: the corrected previous keyframe composed with the raw step (the raw
      // pose itself, exactly, while no solve has corrected anything).
      const Sim3d step = last_raw_.Inverse() * kf->raw;
      graph_.AddVertex(kf->id, solved_ ? graph_.Pose(last_id_) * step : kf->raw, kf->raw);
      PoseGraphEdge edge;
      edge.from = last_id_;
      edge.to = kf->id;
      edge.from_from_to = step;
      if (graph_.vertex_type() != VertexType::kSim3) edge.from_from_to.scale = 1.0;
      edge.information = kf->information ? *kf->information : options_.odometry.Information(step);
      edge.information_from_caller = kf->information.has_value();
      graph_.AddEdge(edge);
    }
    has_last_raw_ = true;
    last_raw_ = kf->raw;
    last_id_ = kf->id;
  } else if (const auto* loop = std::get_if<LoopConstraint>(&message)) {
    try {
      graph_.AddLoop(*loop);
      *new_loops = true;
    } catch (const std::invalid_argument& e) {
      Logger().warn("background optimizer: loop {} -> {} ignored: {}", loop->query_id,
                    loop->match_id, e.what());
    }
  } else {
    *end = true;
  }
}

void BackgroundOptimizer::WaitForIdle() {
  std::unique_lock<std::mutex> lock(mutex_);
  idle_cv_.wait(lock, [&] { return queue_.empty() && !working_; });
}

std::string BackgroundOptimizer::failure() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return failure_;
}

void BackgroundOptimizer::Fail(const std::string& what) {
  Logger().error("background optimizer: pose graph solve failed, no further solves: {}", what);
  std::lock_guard<std::mutex> lock(mutex_);
  if (failure_.empty()) failure_ = what;
}

void BackgroundOptimizer::Run() {
  bool end = false;
  bool pending = false;  // loops added since the last completed solve
  bool failed = false;   // a failure was recorded: messages are drained, nothing is solved
  // A solve is due: pending loops, and solving while running or at the end of the stream.
  auto due = [&] { return pending && (options_.solve_while_running || end); };
  while (true) {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      // Sleep until there is work, unless a solve is due (then just drain what is there).
      if (!due()) {
        if (queue_.empty()) {
          working_ = false;
          idle_cv_.notify_all();
        }
        not_empty_.wait(lock, [&] { return !queue_.empty(); });
        working_ = true;
      }
      std::deque<Message> batch;
      batch.swap(queue_);
      // The flag is reset under the lock with the drain: a loop pushed later sets it again.
      interrupt_.store(false, std::memory_order_release);
      lock.unlock();
      not_full_.notify_all();
      for (const Message& m : batch) {
        if (failed) {
          end = end || std::holds_alternative<EndMsg>(m);
          continue;
        }
        try {
          Apply(m, &end, &pending);
        } catch (const std::exception& e) {
          Fail(e.what());
          failed = true;
          end = end || std::holds_alternative<EndMsg>(m);
        }
      }
    }
    if (failed) pending = false;
    // No exception leaves this thread (std::terminate): a solve that throws (e.g. a chain
    // covariance Cholesky cannot factor) is a failure Finish() reports, and nothing is solved
    // after it.
    if (due() && graph_.num_vertices() >= 2) {
      try {
        const size_t num_loops = graph_.loops().size();
        PoseGraphSummary summary = graph_.Optimize(options_.solve, &interrupt_);
        solved_ = true;
        ++num_solves_;
#if defined(__GLIBC__)
        if (options_.release_memory_after_solve) malloc_trim(0);
#endif
        if (summary.status == PoseGraphStatus::kInterrupted) {
          ++num_interrupted_;
          continue;  // re-solve with the newer loops (warm start from the partial solution)
        }
        pending = false;
        if (callback_) {
          PoseCorrection correction;
          correction.revision = ++revision_;
          correction.num_loops = num_loops;
          correction.ids = graph_.VertexIds();
          correction.world_from_keyframe.reserve(correction.ids.size());
          for (int64_t id : correction.ids)
            correction.world_from_keyframe.push_back(graph_.Pose(id));
          correction.summary = std::move(summary);
          callback_(correction);
        }
      } catch (const std::exception& e) {
        Fail(e.what());
        failed = true;
        pending = false;
      }
    } else if (due()) {
      pending = false;  // fewer than two vertices: nothing to solve
    }
    if (end && !pending) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (queue_.empty()) {
        working_ = false;
        idle_cv_.notify_all();
        break;
      }
    }
  }
}

}  // namespace sparseloop
