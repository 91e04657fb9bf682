// Pose-graph solve time for a SLAM-sized Sim(3) graph: 5,000 keyframes along a drifting
// trajectory with 100 loops. "Cold" solves from the raw poses; "Warm" re-solves after one new loop
// starting from the previous solution (what the background optimizer does in a live system).
#include <random>

#include <benchmark/benchmark.h>

#include "sparseloop/posegraph/pose_graph.h"

namespace sparseloop {
namespace {

struct Graph {
  std::vector<int64_t> ids;
  std::vector<Sim3d> raw;
  std::vector<LoopConstraint> loops;
};

Graph MakeGraph(int num_keyframes, int num_loops) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  Graph g;
  const int laps = 4;
  const int per_lap = num_keyframes / laps;
  std::vector<Sim3d> gt;
  for (int i = 0; i < num_keyframes; ++i) {
    const double a = 2.0 * M_PI * i / per_lap;
    gt.push_back(Sim3d(1.0, Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ())),
                       Eigen::Vector3d(100 * std::cos(a), 100 * std::sin(a), 0)));
    g.ids.push_back(i);
  }
  g.raw.push_back(gt[0]);
  double log_scale = 0;
  for (int i = 1; i < num_keyframes; ++i) {
    const Sim3d rel = gt[i - 1].Inverse() * gt[i];
    log_scale += 0.0005 * n01(rng);
    const Eigen::Quaterniond drift(
        Eigen::AngleAxisd(0.0005 + 0.0005 * n01(rng), Eigen::Vector3d::UnitZ()));
    g.raw.push_back(g.raw.back() *
                    Sim3d(1.0, rel.rotation * drift, std::exp(log_scale) * rel.translation));
  }
  for (int k = 0; k < num_loops; ++k) {
    const int q = per_lap + (num_keyframes - per_lap - 1) * k / num_loops;
    const int m = q % per_lap;
    LoopConstraint l;
    l.query_id = q;
    l.match_id = m;
    l.match_from_query = gt[m].Inverse() * gt[q];
    l.information = LoopInformation(0.1, 0.01, 0.01);
    g.loops.push_back(l);
  }
  return g;
}

void BM_PoseGraphSim3Cold(benchmark::State& state) {
  const Graph g = MakeGraph(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  PoseGraphOptions options;
  int iterations = 0;
  for (auto _ : state) {
    state.PauseTiming();
    PoseGraph graph = BuildOdometryGraph(g.ids, g.raw, VertexType::kSim3);
    for (const auto& l : g.loops) graph.AddLoop(l);
    state.ResumeTiming();
    iterations = graph.Optimize(options).iterations;
  }
  state.counters["lm_iterations"] = iterations;
}
BENCHMARK(BM_PoseGraphSim3Cold)->Args({5000, 100})->Unit(benchmark::kMillisecond)->Iterations(3);

void BM_PoseGraphSim3WarmNewLoop(benchmark::State& state) {
  const Graph g = MakeGraph(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  PoseGraphOptions options;
  PoseGraph base = BuildOdometryGraph(g.ids, g.raw, VertexType::kSim3);
  for (size_t k = 0; k + 1 < g.loops.size(); ++k) base.AddLoop(g.loops[k]);
  base.Optimize(options);  // previous solution
  int iterations = 0;
  for (auto _ : state) {
    state.PauseTiming();
    PoseGraph graph = base;
    graph.AddLoop(g.loops.back());
    state.ResumeTiming();
    iterations = graph.Optimize(options).iterations;
  }
  state.counters["lm_iterations"] = iterations;
}
BENCHMARK(BM_PoseGraphSim3WarmNewLoop)
    ->Args({5000, 100})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

}  // namespace
}  // namespace sparseloop

BENCHMARK_MAIN();
