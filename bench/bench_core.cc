// Micro-benchmarks of the core geometry: the pose-graph residuals call these per edge.
#include <benchmark/benchmark.h>

#include "sparseloop/core/sim3.h"

namespace {

void BM_Sim3ExpLog(benchmark::State& state) {
  sparseloop::Vector7d x;
  x << 0.3, -0.1, 0.2, 0.05, 0.1, -0.2, 0.01;
  for (auto _ : state) {
    const sparseloop::Sim3d g = sparseloop::Sim3d::Exp(x);
    benchmark::DoNotOptimize(g.Log());
  }
}
BENCHMARK(BM_Sim3ExpLog);

void BM_Sim3Compose(benchmark::State& state) {
  sparseloop::Vector7d x;
  x << 0.3, -0.1, 0.2, 0.05, 0.1, -0.2, 0.01;
  const sparseloop::Sim3d a = sparseloop::Sim3d::Exp(x);
  sparseloop::Sim3d b = a;
  for (auto _ : state) {
    b = a * b.Inverse();
    benchmark::DoNotOptimize(b);
  }
}
BENCHMARK(BM_Sim3Compose);

}  // namespace

BENCHMARK_MAIN();
