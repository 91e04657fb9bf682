// BackgroundOptimizer: loops pushed while solving are all processed, and the final estimate
// equals a synchronous solve of the same graph.
#include <atomic>
#include <mutex>
#include <random>
#include <stdexcept>
#include <thread>

#include "sparseloop/runtime/background_optimizer.h"
#include "test_util.h"

namespace sparseloop {
namespace {

// A square-ish loop trajectory driven three times, with heading and scale drift in the raw poses.
struct Data {
  std::vector<Sim3d> gt, raw;
  std::vector<LoopConstraint> loops;
};

Data MakeData() {
  auto rng = test::SeededRng(21);
  std::normal_distribution<double> n01(0.0, 1.0);
  Data d;
  const int per_lap = 120, n = 3 * per_lap;
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * M_PI * i / per_lap;
    d.gt.push_back(Sim3d(1.0, Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ())),
                         Eigen::Vector3d(20 * std::cos(a), 20 * std::sin(a), 0)));
  }
  d.raw.push_back(d.gt[0]);
  double log_scale = 0;
  for (int i = 1; i < n; ++i) {
    const Sim3d rel = d.gt[i - 1].Inverse() * d.gt[i];
    log_scale += 0.002 + 0.002 * n01(rng);
    const Eigen::Quaterniond drift(
        Eigen::AngleAxisd(0.003 + 0.002 * n01(rng), Eigen::Vector3d::UnitZ()));
    d.raw.push_back(d.raw.back() *
                    Sim3d(1.0, rel.rotation * drift, std::exp(log_scale) * rel.translation));
  }
  for (int q = per_lap + 5; q < n; q += 6) {
    const int m = q % per_lap;
    LoopConstraint l;
    l.query_id = q;
    l.match_id = m;
    // Exact Sim(3) between the raw local maps: scale ratio from the raw step lengths.
    const double lq = (d.raw[q].translation - d.raw[q - 1].translation).norm() /
                      (d.gt[q].translation - d.gt[q - 1].translation).norm();
    const double lm = (d.raw[m + 1].translation - d.raw[m].translation).norm() /
                      (d.gt[m + 1].translation - d.gt[m].translation).norm();
    const Sim3d rel = d.gt[m].Inverse() * d.gt[q];
    l.match_from_query = Sim3d(lm / lq, rel.rotation, lm * rel.translation);
    l.information = LoopInformation(0.05, 0.01, 0.01);
    d.loops.push_back(l);
  }
  return d;
}

BackgroundOptimizerOptions Options() {
  BackgroundOptimizerOptions o;
  o.queue_capacity = 8;  // small: exercises the producer's backpressure
  o.solve.function_tolerance = 1e-12;
  o.solve.gradient_tolerance = 1e-14;
  o.solve.parameter_tolerance = 1e-12;
  o.solve.max_iterations = 200;
  return o;
}

TEST(BackgroundOptimizer, AllLoopsProcessedAndFinalEqualsSynchronousSolve) {
  const Data d = MakeData();
  ASSERT_GE(d.loops.size(), 20u);
  std::mutex mutex;
  std::vector<PoseCorrection> corrections;
  BackgroundOptimizer optimizer(Options(), [&](const PoseCorrection& c) {
    std::lock_guard<std::mutex> lock(mutex);
    corrections.push_back(c);
  });
  // Producer thread: keyframes in time order, each loop as soon as its query keyframe exists,
  // so loops arrive while earlier solves are running.
  std::thread producer([&] {
    size_t next_loop = 0;
    for (size_t i = 0; i < d.raw.size(); ++i) {
      ASSERT_TRUE(optimizer.PushKeyframe(static_cast<int64_t>(i), d.raw[i]));
      while (next_loop < d.loops.size() && d.loops[next_loop].query_id == static_cast<int64_t>(i)) {
        ASSERT_TRUE(optimizer.PushLoop(d.loops[next_loop++]));
      }
    }
  });
  producer.join();
  optimizer.Finish();
  EXPECT_FALSE(optimizer.PushLoop(d.loops[0]));  // closed after Finish

  const PoseGraph& graph = optimizer.graph();
  ASSERT_EQ(graph.num_vertices(), d.raw.size());
  ASSERT_EQ(graph.loops().size(), d.loops.size());
  ASSERT_FALSE(corrections.empty());
  EXPECT_EQ(corrections.back().num_loops, d.loops.size());
  for (size_t i = 1; i < corrections.size(); ++i) {
    EXPECT_EQ(corrections[i].revision, corrections[i - 1].revision + 1);
    EXPECT_GE(corrections[i].num_loops, corrections[i - 1].num_loops);
  }
  std::cerr << "background: " << optimizer.num_solves() << " solves, "
            << optimizer.num_interrupted() << " interrupted, " << corrections.size()
            << " corrections delivered\n";

  // Synchronous solve of the same graph from the raw poses.
  std::vector<int64_t> ids(d.raw.size());
  for (size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<int64_t>(i);
  PoseGraph sync = BuildOdometryGraph(ids, d.raw, VertexType::kSim3, Options().odometry);
  for (const auto& l : d.loops) sync.AddLoop(l);
  const PoseGraphSummary s = sync.Optimize(Options().solve);
  ASSERT_NE(s.status, PoseGraphStatus::kFailed);
  double max_diff = 0.0;
  for (int64_t id : ids) {
    max_diff = std::max(max_diff, (graph.Pose(id).translation - sync.Pose(id).translation).norm());
  }
  std::cerr << "max |background - synchronous| = " << max_diff << " m (path radius 20 m)\n";
  EXPECT_LT(max_diff, 1e-3);
  // And the last delivered correction is that final estimate.
  const PoseCorrection& last = corrections.back();
  for (size_t k = 0; k < last.ids.size(); ++k) {
    ASSERT_LT(
        (last.world_from_keyframe[k].ToMatrix4() - graph.Pose(last.ids[k]).ToMatrix4()).norm(),
        1e-12);
  }
}

// Stress: the same stream through queues from 1 message (every push waits for the optimiser) to
// the default, several times each, with loops interrupting solves at different moments. No
// deadlock (ctest's timeout), every loop in the graph, and the same final estimate every time.
TEST(BackgroundOptimizer, StressAnyQueueCapacityGivesTheSameFinalEstimate) {
  const Data d = MakeData();
  std::vector<Sim3d> reference;
  int runs = 0;
  for (size_t capacity : {size_t{1}, size_t{2}, size_t{7}, size_t{256}}) {
    for (int repeat = 0; repeat < 2; ++repeat) {
      BackgroundOptimizerOptions o = Options();
      o.queue_capacity = capacity;
      std::atomic<int> delivered{0};
      BackgroundOptimizer optimizer(o, [&](const PoseCorrection&) { ++delivered; });
      std::thread producer([&] {
        size_t next_loop = 0;
        for (size_t i = 0; i < d.raw.size(); ++i) {
          EXPECT_TRUE(optimizer.PushKeyframe(static_cast<int64_t>(i), d.raw[i]));
          while (next_loop < d.loops.size() &&
                 d.loops[next_loop].query_id == static_cast<int64_t>(i))
            EXPECT_TRUE(optimizer.PushLoop(d.loops[next_loop++]));
        }
      });
      producer.join();
      optimizer.Finish();
      ++runs;
      const PoseGraph& g = optimizer.graph();
      ASSERT_EQ(g.num_vertices(), d.raw.size()) << "capacity " << capacity;
      ASSERT_EQ(g.loops().size(), d.loops.size()) << "capacity " << capacity;
      EXPECT_GE(delivered.load(), 1) << "capacity " << capacity;
      if (reference.empty()) {
        for (size_t i = 0; i < d.raw.size(); ++i) reference.push_back(g.Pose(int64_t(i)));
        continue;
      }
      double max_diff = 0.0;
      for (size_t i = 0; i < d.raw.size(); ++i)
        max_diff =
            std::max(max_diff, (g.Pose(int64_t(i)).translation - reference[i].translation).norm());
      // Converged solves from different warm starts agree to the solver tolerance, not bitwise.
      EXPECT_LT(max_diff, 1e-3) << "capacity " << capacity << ", repeat " << repeat;
    }
  }
  EXPECT_EQ(runs, 8);
}

TEST(BackgroundOptimizer, FinishWithoutLoopsDeliversNothingAndIsIdempotent) {
  int calls = 0;
  BackgroundOptimizer optimizer(Options(), [&](const PoseCorrection&) { ++calls; });
  optimizer.PushKeyframe(0, Sim3d());
  optimizer.PushKeyframe(1, Sim3d(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0)));
  optimizer.Finish();
  optimizer.Finish();
  EXPECT_EQ(calls, 0);
  EXPECT_EQ(optimizer.graph().num_vertices(), 2u);
  EXPECT_EQ(optimizer.num_solves(), 0u);
}

// An exception in the background thread (a solve whose chain reduction's Cholesky failed on a
// covariance of 1e-30, a callback that throws) was std::terminate: it is caught, logged and
// reported by failure(), and nothing is solved after it.
TEST(BackgroundOptimizer, AFailingSolveIsReportedNotTerminate) {
  const Data d = MakeData();
  int calls = 0;
  BackgroundOptimizerOptions options = Options();
  options.solve_while_running = false;
  BackgroundOptimizer optimizer(options, [&](const PoseCorrection&) {
    ++calls;
    throw std::runtime_error("callback failed");
  });
  for (size_t i = 0; i < d.raw.size(); ++i)
    optimizer.PushKeyframe(static_cast<int64_t>(i), d.raw[i]);
  for (const LoopConstraint& l : d.loops) optimizer.PushLoop(l);
  optimizer.Finish();
  EXPECT_EQ(optimizer.failure(), "callback failed");
  EXPECT_EQ(calls, 1);
}

TEST(PoseGraphInterrupt, RaisedFlagStopsTheSolve) {
  const Data d = MakeData();
  std::vector<int64_t> ids(d.raw.size());
  for (size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<int64_t>(i);
  PoseGraph graph = BuildOdometryGraph(ids, d.raw, VertexType::kSim3);
  for (const auto& l : d.loops) graph.AddLoop(l);
  std::atomic<bool> flag{true};
  const PoseGraphSummary s = graph.Optimize(PoseGraphOptions{}, &flag);
  EXPECT_EQ(s.status, PoseGraphStatus::kInterrupted);
  EXPECT_LE(s.iterations, 1);
  flag = false;
  const PoseGraphSummary s2 = graph.Optimize(PoseGraphOptions{}, &flag);
  EXPECT_NE(s2.status, PoseGraphStatus::kInterrupted);
}

}  // namespace
}  // namespace sparseloop
