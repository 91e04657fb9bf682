// SearchArea query cost with 1k, 10k, 100k stored keyframes, per strategy.
// The trajectory is a chain of overlapping square loops (side 40 m, 1 m steps, each loop shifted
// 20 m east of the previous one, a slow heading wobble and noise), so every place is revisited a
// bounded number of times and the covered area grows with the trajectory, as in a long drive.
// Expected: paper and radius ~flat in N (grid), global linear (its answer is the whole past).
#include <cmath>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "sparseloop/search/search_area.h"

namespace {

using sparseloop::SearchArea;
using sparseloop::SearchAreaOptions;
using sparseloop::SearchStrategy;

std::vector<Eigen::Vector3d> ChainOfLoops(int n) {
  std::mt19937_64 rng(42);
  std::normal_distribution<double> noise(0.0, 0.2);
  std::vector<Eigen::Vector3d> pts;
  pts.reserve(n);
  const double side = 40.0;
  for (int k = 0; pts.size() < static_cast<size_t>(n); ++k) {
    const int loop = k / 160;
    const int along = k % 160;  // 4 sides x 40 steps of 1 m
    const double s = along % 40;
    Eigen::Vector2d xy;
    switch (along / 40) {
      case 0:
        xy = {s, 0};
        break;
      case 1:
        xy = {side, s};
        break;
      case 2:
        xy = {side - s, side};
        break;
      default:
        xy = {0, side - s};
        break;
    }
    xy += Eigen::Vector2d(20.0 * loop, 3.0 * std::sin(0.3 * loop));
    pts.emplace_back(xy.x() + noise(rng), 0.1 * noise(rng), xy.y() + noise(rng));
  }
  return pts;
}

SearchAreaOptions Options(SearchStrategy strategy) {
  SearchAreaOptions o;
  o.strategy = strategy;
  o.drift_rate = 0.0;                         // the paper's area (or the radius) alone
  o.plane_normal = Eigen::Vector3d::UnitY();  // KITTI-like: ground plane x-z
  o.exclude_recent = 50;
  o.radius = 10.0;
  return o;
}

void BM_Query(benchmark::State& state, SearchStrategy strategy) {
  const int n = static_cast<int>(state.range(0));
  const auto pts = ChainOfLoops(n);
  SearchArea area(Options(strategy));
  for (int k = 0; k < n; ++k) area.Add(k, pts[k]);
  // A loop was accepted ~800 keyframes ago.
  area.OnLoopAccepted(n - 1 - 800 > 0 ? n - 1 - 800 : 0, 0);
  // Query the most recent 256 keyframes in turn (the area only looks at earlier keyframes).
  int i = 0;
  size_t candidates = 0, cells = 0, queries = 0;
  for (auto _ : state) {
    const auto r = area.Query(n - 1 - (i++ % 256));
    candidates += r.candidates.size();
    cells += r.cells_visited;
    ++queries;
    benchmark::DoNotOptimize(r.candidates.data());
  }
  state.counters["candidates"] = static_cast<double>(candidates) / queries;
  state.counters["cells"] = static_cast<double>(cells) / queries;
}

void BM_Add(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const auto pts = ChainOfLoops(n);
  for (auto _ : state) {
    SearchAreaOptions o = Options(SearchStrategy::kPaper);
    o.plane_normal.reset();  // include the PCA refits
    SearchArea area(o);
    for (int k = 0; k < n; ++k) area.Add(k, pts[k]);
    benchmark::DoNotOptimize(area.size());
  }
  state.SetItemsProcessed(state.iterations() * n);
}

BENCHMARK_CAPTURE(BM_Query, paper, SearchStrategy::kPaper)->Arg(1000)->Arg(10000)->Arg(100000);
BENCHMARK_CAPTURE(BM_Query, radius, SearchStrategy::kRadius)->Arg(1000)->Arg(10000)->Arg(100000);
BENCHMARK_CAPTURE(BM_Query, global, SearchStrategy::kGlobal)->Arg(1000)->Arg(10000)->Arg(100000);
BENCHMARK(BM_Add)->Arg(1000)->Arg(10000)->Arg(100000)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
