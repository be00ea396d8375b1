// Simulator speed: one warm-started contact solve per path point, and whole scenarios.
//   build/release/benchmarks/bench_sim --benchmark_repetitions=5
//   --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include "traverse/io/rover_description.h"
#include "traverse/sim/contact_solver.h"
#include "traverse/sim/simulator.h"

namespace {

using namespace traverse;

const std::filesystem::path kDatasets = std::filesystem::path(TRAVERSE_SOURCE_DIR) / "datasets";

const rover::RoverGeometry& rocky7() {
  static const rover::RoverGeometry geo = [] {
    const auto dir = kDatasets / "rovers" / "rocky7";
    return io::loadRoverGeometry(dir / "rover.urdf", io::loadRoverConfig(dir / "rover.yaml"));
  }();
  return geo;
}

// A 1 m straight path at 2.5 mm spacing over K-22: the cost of one warm-started solve.
void BM_ContactSolveUndulating(benchmark::State& state) {
  const sim::UndulatingTerrain terrain;
  const sim::ContactSolver solver(rocky7(), terrain);
  long solves = 0;
  for (auto _ : state) {
    sim::ContactState s = solver.initialGuess(0, 0, 0);
    for (int k = 0; k <= 400; ++k, ++solves) {
      s = solver.solve(k * 0.0025, 0.0, 0.0, Vec2d::Zero(), s);
    }
    benchmark::DoNotOptimize(s);
  }
  state.SetItemsProcessed(solves);
}
BENCHMARK(BM_ContactSolveUndulating)->Unit(benchmark::kMillisecond);

void BM_SimulateScenario(benchmark::State& state, const char* name) {
  const sim::Scenario sc = sim::loadScenario(name, kDatasets);
  for (auto _ : state) {
    benchmark::DoNotOptimize(sim::simulate(sc, kDatasets / "rovers" / "rocky7", 1));
  }
}
BENCHMARK_CAPTURE(BM_SimulateScenario, straight_1m, "straight-1m")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SimulateScenario, multi_stop, "multi-stop")
    ->Unit(benchmark::kSecond)
    ->Iterations(1);

}  // namespace
