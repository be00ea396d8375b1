// EKF step cost: propagation + six-wheel slip update (24 rows, sequential per wheel) + sun
// update, on a real state from the bundled multi-stop log (issue 4 target: ≥ 100 000 steps/s).
// The log's rover.yaml declares the common slip c (the simulator states the slip its wheels
// share, docs/simulator.md): the issue-4 figures (BM_EkfStep, …) are of the 21-state filter
// without it, as the target was set; BM_EkfStepCommonSlip is the same step with c (23 states).
//   build/release/benchmarks/bench_ekf --benchmark_repetitions=5
//   --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include "traverse/estimators/ekf.h"
#include "traverse/io/log_reader.h"

namespace {

using namespace traverse;

struct Setup {
  io::TraverseLog log;
  io::RoverConfig without_c;  ///< the log's rover.yaml without the common slip: 21 states
  est::Segmentation seg;
  est::InitialState init;
  std::vector<est::JointSample> joints;
};

const Setup& setup() {
  static const Setup s = [] {
    Setup x;
    x.log = io::readLog(std::filesystem::path(TRAVERSE_SOURCE_DIR) / "datasets" / "logs" /
                        "multi-stop");
    x.seg = est::segment(x.log);
    x.init = est::initialState(x.log, x.seg);
    x.joints = est::jointSamples(x.log);
    x.without_c = x.log.config;
    x.without_c.slip_noise.common_longitudinal_mps = 0.0;
    x.without_c.slip_noise.common_lateral_mps = 0.0;
    return x;
  }();
  return s;
}

est::EkfInputs inputs(const Setup& s, size_t k) {
  est::EkfInputs in;
  in.gyro = Vec3d(0, 0, s.log.gyro.values(static_cast<Eigen::Index>(2 * k), 0));
  const auto c = s.log.cmd->values.row(static_cast<Eigen::Index>(k));
  in.v_cmd = c.head<3>().transpose(), in.w_cmd = c.tail<3>().transpose();
  return in;
}

// Walks the motion part of the log: each iteration = one joint sample's worth of filter work.
void step(benchmark::State& state, const io::RoverConfig& config) {
  const Setup& s = setup();
  est::Ekf ekf(config, s.log.geometry, {}, s.init, false, true);
  const size_t first = 150, count = 400;  // joint samples 15 s … 55 s: the first leg, moving
  size_t k = first;
  const Vec2d sun = s.log.sun->values.row(20).head<2>().transpose();
  for (auto _ : state) {
    const est::EkfInputs in = inputs(s, k);
    ekf.propagate(0.1, in);
    ekf.updateSlip(s.joints[k], in);
    ekf.updateSun(sun, s.log.config.sun.direction_site);
    if (++k == first + count) k = first;
  }
  state.SetItemsProcessed(state.iterations());
}
void BM_EkfStep(benchmark::State& state) {
  step(state, setup().without_c);
}
BENCHMARK(BM_EkfStep);
void BM_EkfStepCommonSlip(benchmark::State& state) {
  step(state, setup().log.config);
}
BENCHMARK(BM_EkfStepCommonSlip);

void BM_EkfPropagate(benchmark::State& state) {
  const Setup& s = setup();
  est::Ekf ekf(s.without_c, s.log.geometry, {}, s.init, false, true);
  const est::EkfInputs in = inputs(s, 200);
  for (auto _ : state) ekf.propagate(0.1, in);
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_EkfPropagate);

void BM_EkfSlipUpdate(benchmark::State& state) {
  const Setup& s = setup();
  est::Ekf ekf(s.without_c, s.log.geometry, {}, s.init, false, true);
  const est::EkfInputs in = inputs(s, 200);
  for (auto _ : state) ekf.updateSlip(s.joints[200], in);
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_EkfSlipUpdate);

void BM_EkfSunUpdate(benchmark::State& state) {
  const Setup& s = setup();
  est::Ekf ekf(s.without_c, s.log.geometry, {}, s.init, false, true);
  const Vec2d sun = s.log.sun->values.row(20).head<2>().transpose();
  for (auto _ : state) ekf.updateSun(sun, s.log.config.sun.direction_site);
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_EkfSunUpdate);

// The whole filter over the 781 s multi-stop log (7811 joint samples, 15621 gyro samples), as
// bundled (with c).
void BM_EkfWholeLog(benchmark::State& state) {
  const Setup& s = setup();
  for (auto _ : state) benchmark::DoNotOptimize(est::runEkf(s.log, s.seg, s.init));
}
BENCHMARK(BM_EkfWholeLog)->Unit(benchmark::kMillisecond);

}  // namespace
