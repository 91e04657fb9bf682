// Pose-graph solve time for a SLAM-sized Sim(3) graph: 5,000 keyframes along a drifting
// trajectory with 100 loops. "Cold" solves from the raw poses; "Warm" re-solves after one new loop
// starting from the previous solution (what the background optimizer does in a live system).
// The default options reduce the odometry chains (PoseGraphOptions::reduce_chains); the
// "FullGraph" cases solve every vertex, the baseline measured in the same run, and the default
// cases report their largest position difference to it. Both report how far they stopped from the
// full graph's minimum (max_diff_to_optimum_m, cost_vs_optimum; a tight full solve, untimed).
#include <algorithm>
#include <memory>
#include <random>

#include <benchmark/benchmark.h>

#include "posegraph/edge_error.h"
#include "posegraph/manifolds.h"
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

// The options of a case: the default (chain reduction) or the full graph in the solve.
PoseGraphOptions SolveOptions(bool reduce_chains) {
  PoseGraphOptions options;
  options.reduce_chains = reduce_chains;
  return options;
}

// The reference minimum: every vertex in the solve, run to a tight tolerance.
PoseGraphOptions TightFullOptions() {
  PoseGraphOptions options = SolveOptions(false);
  options.function_tolerance = 1e-12;
  options.parameter_tolerance = 1e-12;
  return options;
}

// Largest vertex position difference between two solved graphs (same ids).
double MaxPositionDifference(const PoseGraph& a, const PoseGraph& b) {
  double out = 0.0;
  for (int64_t id : a.VertexIds()) {
    out = std::max(out, (a.Pose(id).translation - b.Pose(id).translation).norm());
  }
  return out;
}

void Sim3Cold(benchmark::State& state, bool reduce_chains) {
  const Graph g = MakeGraph(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const PoseGraphOptions options = SolveOptions(reduce_chains);
  PoseGraph graph = BuildOdometryGraph(g.ids, g.raw, VertexType::kSim3);
  for (const auto& l : g.loops) graph.AddLoop(l);
  const PoseGraph initial = graph;
  PoseGraphSummary summary;
  for (auto _ : state) {
    state.PauseTiming();
    graph = initial;
    state.ResumeTiming();
    summary = graph.Optimize(options);
  }
  state.counters["lm_iterations"] = summary.iterations;
  state.counters["solve_ms"] = 1e3 * summary.solve_seconds;
  state.counters["pcm_ms"] = 1e3 * summary.rejection_seconds;
  state.counters["solved_vertices"] = static_cast<double>(summary.num_solved_vertices);
  state.counters["final_cost"] = summary.final_cost;
  // Accuracy next to the speed: distance to the full graph's minimum, outside the timed loop.
  PoseGraph optimum = initial;
  const PoseGraphSummary optimum_summary = optimum.Optimize(TightFullOptions());
  state.counters["max_diff_to_optimum_m"] = MaxPositionDifference(graph, optimum);
  state.counters["cost_vs_optimum"] = summary.final_cost / optimum_summary.final_cost;
}
void BM_PoseGraphSim3Cold(benchmark::State& state) { Sim3Cold(state, true); }
void BM_PoseGraphSim3ColdFullGraph(benchmark::State& state) { Sim3Cold(state, false); }
BENCHMARK(BM_PoseGraphSim3Cold)->Args({5000, 100})->Unit(benchmark::kMillisecond)->Iterations(5);
BENCHMARK(BM_PoseGraphSim3ColdFullGraph)
    ->Args({5000, 100})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

void Sim3WarmNewLoop(benchmark::State& state, bool reduce_chains) {
  const Graph g = MakeGraph(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const PoseGraphOptions options = SolveOptions(reduce_chains);
  PoseGraph base = BuildOdometryGraph(g.ids, g.raw, VertexType::kSim3);
  for (size_t k = 0; k + 1 < g.loops.size(); ++k) base.AddLoop(g.loops[k]);
  base.Optimize(options);  // previous solution
  base.AddLoop(g.loops.back());
  PoseGraph graph = base;
  PoseGraphSummary summary;
  for (auto _ : state) {
    state.PauseTiming();
    graph = base;
    state.ResumeTiming();
    summary = graph.Optimize(options);
  }
  state.counters["lm_iterations"] = summary.iterations;
  state.counters["solved_vertices"] = static_cast<double>(summary.num_solved_vertices);
  PoseGraph optimum = base;
  const PoseGraphSummary optimum_summary = optimum.Optimize(TightFullOptions());
  state.counters["max_diff_to_optimum_m"] = MaxPositionDifference(graph, optimum);
  state.counters["cost_vs_optimum"] = summary.final_cost / optimum_summary.final_cost;
}
void BM_PoseGraphSim3WarmNewLoop(benchmark::State& state) { Sim3WarmNewLoop(state, true); }
void BM_PoseGraphSim3WarmNewLoopFullGraph(benchmark::State& state) {
  Sim3WarmNewLoop(state, false);
}
BENCHMARK(BM_PoseGraphSim3WarmNewLoop)
    ->Args({5000, 100})
    ->Args({30000, 2000})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(5);
BENCHMARK(BM_PoseGraphSim3WarmNewLoopFullGraph)
    ->Args({5000, 100})
    ->Args({30000, 2000})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

// One Sim(3) edge evaluation with Jacobians: autodiff (EdgeError) vs analytic (Sim3EdgeCost).
void EdgeJacobian(benchmark::State& state, bool analytic) {
  const Sim3d a = Sim3d::Exp((Vector7d() << 1, 2, 3, 0.1, 0.2, 0.3, 0.05).finished());
  const Sim3d b = Sim3d::Exp((Vector7d() << 1.5, 2, 3, 0.1, 0.25, 0.3, 0.06).finished());
  const Sim3d z =
      Sim3d::Exp((Vector7d() << 0.01, 0, 0, 0, 0.01, 0, 0.001).finished()) * a.Inverse() * b;
  std::unique_ptr<ceres::CostFunction> cost(analytic ? Sim3EdgeCost::Create(z, Matrix7d::Identity())
                                                     : EdgeError::Create(z, Matrix7d::Identity()));
  Vector8d av = a.ToVector(), bv = b.ToVector();
  const double* params[2] = {av.data(), bv.data()};
  double r[7], ja[56], jb[56];
  double* jac[2] = {ja, jb};
  for (auto _ : state) {
    cost->Evaluate(params, r, jac);
    benchmark::DoNotOptimize(ja[0]);
  }
}
// PCM when one loop arrives in a graph that already has `loops` loops (what every background
// re-solve does): arg 1 = 0 evaluates every pair again (PcmConsistentLoops), 1 only the new
// loop's pairs (PcmConsistentLoopsIncremental, what Optimize uses). Same clique either way.
void BM_PcmNewLoop(benchmark::State& state) {
  const int num_loops = static_cast<int>(state.range(0));
  const bool incremental = state.range(1) != 0;
  const Graph g = MakeGraph(20000, num_loops + 1);
  PoseGraph graph = BuildOdometryGraph(g.ids, g.raw, VertexType::kSim3);
  for (int k = 0; k < num_loops; ++k) graph.AddLoop(g.loops[k]);
  const PcmOptions options;
  graph.PcmConsistentLoopsIncremental(options);  // the cache of the earlier solves
  size_t kept = 0;
  for (auto _ : state) {
    state.PauseTiming();
    PoseGraph trial = graph;  // the graph before the new loop, cache included
    trial.AddLoop(g.loops[num_loops]);
    state.ResumeTiming();
    kept = incremental ? trial.PcmConsistentLoopsIncremental(options).size()
                       : trial.PcmConsistentLoops(options).size();
    benchmark::DoNotOptimize(kept);
  }
  state.counters["kept"] = static_cast<double>(kept);
}
BENCHMARK(BM_PcmNewLoop)
    ->ArgsProduct({{500, 2000}, {0, 1}})
    ->ArgNames({"loops", "incremental"})
    ->Unit(benchmark::kMillisecond);

void BM_EdgeJacobianAutodiff(benchmark::State& state) { EdgeJacobian(state, false); }
void BM_EdgeJacobianAnalytic(benchmark::State& state) { EdgeJacobian(state, true); }
BENCHMARK(BM_EdgeJacobianAutodiff);
BENCHMARK(BM_EdgeJacobianAnalytic);

// The Sim(3) manifold's PlusJacobian (called per vertex at every new state): closed form
// (Sim3Manifold) vs ceres::AutoDiffManifold (15-dimensional Jets through exp).
template <typename M>
void BM_Sim3PlusJacobian(benchmark::State& state) {
  const M manifold;
  const Vector8d x = Sim3d::Exp((Vector7d() << 1, 2, 3, 0.1, 0.2, 0.3, 0.05).finished()).ToVector();
  double jacobian[56];
  for (auto _ : state) {
    manifold.PlusJacobian(x.data(), jacobian);
    benchmark::DoNotOptimize(jacobian[0]);
  }
}
BENCHMARK(BM_Sim3PlusJacobian<Sim3AutoDiffManifold>)->Name("BM_Sim3PlusJacobianAutodiff");
BENCHMARK(BM_Sim3PlusJacobian<Sim3Manifold>)->Name("BM_Sim3PlusJacobianClosedForm");

}  // namespace
}  // namespace sparseloop

BENCHMARK_MAIN();
