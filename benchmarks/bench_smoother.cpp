// Smoother speed on one synthetic long segment of 1 000, 10 000 and 100 000 nodes: straight-1m
// stretched (rest, straight L m at 0.05 m/s, rest, each rest a tenth of the segment; joints at
// 20 Hz, so one node per 50 ms) over rough terrain (2 cm RMS, statistically the same everywhere:
// K-22's sin(0.75 x y) gets ever rougher across the path with x, and has no contact configuration
// by x ≈ 49 m), and solved as ONE segment spanning every node with both rest windows. Each
// iteration is one solveSegment (build + Levenberg-Marquardt + marginal covariances,
// single-threaded Ceres). Counters: time per node per LM iteration, total to convergence, the
// solver's own split, and the peak resident memory during the timed runs (VmHWM, reset after
// set-up; process-wide, so run one size per process — scripts/run_smoother_bench.sh does, and
// prints the scaling table).
//   build/release/benchmarks/bench_smoother --benchmark_filter='^BM_SmoothSegment/1000/'
// BM_ScalingRatio/N times N against 10 N nodes in one process, interleaved: each round is ten
// N-node solves then one 10 N-node solve, and the round's ratio is the large solve
// over the median small one. This VM's speed drifts by 15–40 % between minutes (shared memory
// bandwidth), so ratios taken from separate processes minutes apart measure the drift as much as
// the code; adjacent solves see the same machine. It reports the median ratio and its range,
// and per phase (SegmentSummary's split: build, seed, Ceres' preprocessing, Jacobian and
// residual evaluations, linear solves, the rest of its minimiser, covariance, and "other" —
// the elimination ordering, post-processing and teardown) the large solve's mean time (ms_*) and
// its ratio to the small solve's (x_*), so a phase that grows faster than the node count shows. Set
// TRAVERSE_SMOOTHER_REPORT=1 to print Ceres' full report (time breakdown) per solve, and
// TRAVERSE_BENCH_CACHE=DIR to keep the simulated logs in DIR between runs (the 10 000-node log
// takes ~50 s to simulate; the log reads back bit for bit, io/log_writer.h).
#include <benchmark/benchmark.h>
#include <malloc.h>  // malloc_trim
#include <sys/resource.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include "traverse/core/memory.h"
#include "traverse/io/log_reader.h"
#include "traverse/io/log_writer.h"
#include "traverse/pipeline/pipeline.h"
#include "traverse/sim/simulator.h"
#include "traverse/smoother/segment_problem.h"

namespace {

using namespace traverse;

/// True when the environment variable is set to 1.
bool envFlag(const char* name) {
  const char* v = std::getenv(name);
  return v != nullptr && std::string(v) == "1";
}

/// The allocator set up as the traverse CLI sets it (core/memory.h): freed memory stays in the
/// process for the next solve. TRAVERSE_BENCH_DEFAULT_MALLOC=1 leaves glibc's defaults, to
/// measure the difference.
const bool kAllocatorSetUp = !envFlag("TRAVERSE_BENCH_DEFAULT_MALLOC") && retainFreedMemory();

const std::filesystem::path kDatasets = std::filesystem::path(TRAVERSE_SOURCE_DIR) / "datasets";

/// A /proc/self/status field in kB (VmRSS, VmHWM), -1 if absent.
long statusKb(const std::string& field) {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(field + ":", 0) == 0) return std::stol(line.substr(field.size() + 1));
  }
  return -1;
}

/// Minor page faults of this process so far (first touches of fresh pages).
double minorFaults() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_minflt);
}

/// Resets VmHWM to the current RSS (Linux ≥ 4.0); false if the kernel refuses.
bool resetPeakRss() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  out.flush();
  return static_cast<bool>(out);
}

struct Case {
  io::TraverseLog log;
  pipeline::Estimates est;
  std::unique_ptr<smoother::SmootherData> data;  // refers to log and est.ekf.trajectory
  smoother::SegmentSpec spec;
  double sim_seconds = 0.0, estimate_seconds = 0.0;
};

smoother::SmootherOptions options(bool covariance) {
  smoother::SmootherOptions o;
  o.covariance = covariance;
  o.threads = 1;
  o.solver_report = envFlag("TRAVERSE_SMOOTHER_REPORT");
  return o;
}

/// straight-1m with a straight leg long enough for `nodes` joint samples: the leg lasts
/// ramp_s + L / v = 2 + L / 0.05 s between two 5 s rests, and joints run at 20 Hz.
const Case& syntheticSegment(int nodes) {
  static std::map<int, std::unique_ptr<Case>> cache;
  auto& slot = cache[nodes];
  if (slot) return *slot;
  auto c = std::make_unique<Case>();
  // Each rest window is a tenth of the segment (5 s at 1 000 nodes, 50 s at 10 000), so 10x the
  // nodes is the same segment 10x longer: rest nodes cost less than moving ones (no gyro or
  // accelerometer process), and with fixed 5 s rests the 1 000-node case would be 20 % rest and
  // the 10 000-node one 2 %, which inflates the time ratio by itself (about 2 %).
  // TRAVERSE_BENCH_FIXED_RESTS=1 keeps 5 s rests at every size (the sessions-2-to-4 definition).
  const bool fixed_rests = envFlag("TRAVERSE_BENCH_FIXED_RESTS");
  const double speed = 0.05, ramp = 2.0, joints_hz = 20.0;
  const double rest = fixed_rests ? 5.0 : 0.1 * nodes / joints_hz;
  const double length = speed * (nodes / joints_hz - 2.0 * rest - ramp);
  std::ostringstream name;
  name << "smoother-bench-" << nodes << (fixed_rests ? "" : "-rest" + std::to_string(int(rest)));
  const sim::Scenario sc = sim::loadScenario(
      "straight-1m", kDatasets,
      {"name=" + name.str(), "path.0.rest=" + std::to_string(rest),
       "path.1.straight=" + std::to_string(length), "path.2.rest=" + std::to_string(rest),
       "terrain.type=rough", "truth_rate_hz=200", "truth_output_hz=10"});
  auto t0 = std::chrono::steady_clock::now();
  const char* cache_dir = std::getenv("TRAVERSE_BENCH_CACHE");
  const std::filesystem::path cached =
      cache_dir ? std::filesystem::path(cache_dir) / sc.name : std::filesystem::path();
  if (cache_dir && std::filesystem::exists(cached / "joints.csv")) {
    c->log = io::readLog(cached);
  } else {
    sim::Simulation s = sim::simulate(sc, sim::roverDirectory(sc, kDatasets), 1);
    c->log = std::move(s.log);
    if (cache_dir) {
      io::writeLog(cached, c->log);
      c->log = io::readLog(cached);  // the same samples, and the same log.dir either way
    }
  }  // the truth samples go here
  auto t1 = std::chrono::steady_clock::now();
  c->sim_seconds = std::chrono::duration<double>(t1 - t0).count();
  c->est = pipeline::estimate(c->log);  // segmentation, initial state, dead reckoning, EKF
  c->estimate_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  c->data = std::make_unique<smoother::SmootherData>(c->log, c->est.ekf.trajectory, options(true));
  // One segment over every node (an exact count: the last node or two of the final rest may go).
  c->spec.first = 0;
  c->spec.last = std::min(c->data->nodes.size(), static_cast<size_t>(nodes)) - 1;
  for (const est::RestWindow& w : c->est.segmentation.rests) c->spec.rests.push_back(&w);
  slot = std::move(c);
  malloc_trim(0);  // hand the simulation's memory back, so the RSS baseline is the set-up's
  return *slot;
}

void smoothSegment(benchmark::State& state, bool covariance) {
  const Case& c = syntheticSegment(static_cast<int>(state.range(0)));
  const smoother::SmootherOptions o = options(covariance);
  const long rss_before_kb = statusKb("VmRSS");
  const bool peak_reset = resetPeakRss();
  // One untimed solve first, at every size: the allocator's heap then holds the pages every
  // timed solve reuses (1k averages 10 solves, 10k 5 and 100k 1, so a cold first solve would
  // weigh 10x more at 100k than at 1k). First-touch cost is reported by page_faults_per_solve.
  if (!envFlag("TRAVERSE_BENCH_COLD")) {
    smoother::SegmentSolution warm = smoother::solveSegment(*c.data, c.spec, o);
    benchmark::DoNotOptimize(warm);
  }
  double solve = 0, build = 0, cov = 0, iterations = 0;
  smoother::SegmentSummary last;
  const double faults_before = minorFaults();
  for (auto _ : state) {
    smoother::SegmentSolution sol = smoother::solveSegment(*c.data, c.spec, o);
    last = sol.summary;
    solve += last.solve_seconds, build += last.build_seconds, cov += last.covariance_seconds;
    iterations += last.iterations;
    benchmark::DoNotOptimize(sol);
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["page_faults_per_solve"] = (minorFaults() - faults_before) / n;
  const double nodes = static_cast<double>(last.num_nodes);
  solve /= n, build /= n, cov /= n, iterations /= n;
  state.counters["nodes"] = nodes;
  state.counters["lm_iterations"] = iterations;  // rejected steps included
  state.counters["build_s"] = build;
  state.counters["solve_s"] = solve;  // includes build_s
  state.counters["covariance_s"] = cov;
  state.counters["total_s"] = solve + cov;
  state.counters["us_per_node_iter"] = (solve - build) / (nodes * iterations) * 1e6;
  state.counters["residual_blocks"] = last.residual_blocks;
  state.counters["parameters"] = last.parameters;
  state.counters["peak_rss_MB"] = peak_reset ? statusKb("VmHWM") / 1024.0 : -1.0;
  state.counters["rss_before_MB"] = rss_before_kb / 1024.0;
  state.counters["setup_sim_s"] = c.sim_seconds;
  state.counters["setup_est_s"] = c.estimate_seconds;
  state.SetLabel(std::string(smoother::toString(last.status)) + ", " +
                 std::to_string(c.est.segmentation.segments.size()) + " segmentation segments, " +
                 std::to_string(c.spec.rests.size()) + " rests");
}

void BM_SmoothSegment(benchmark::State& state) {
  smoothSegment(state, true);
}
void BM_SmoothSegmentNoCovariance(benchmark::State& state) {
  smoothSegment(state, false);
}

/// One solveSegment's wall time split by phase (SegmentSummary's timings). "other" is the rest:
/// building the elimination ordering, Ceres' post-processing, copying the solution out, and
/// tearing the problem down.
struct Phases {
  static constexpr std::array<const char*, 9> kNames = {
      "build",           "seed",       "preprocess", "jacobian", "residual", "linear",
      "minimizer_other", "covariance", "other"};
  std::array<double, kNames.size()> s{};
  double total() const { return std::accumulate(s.begin(), s.end(), 0.0); }
  Phases& operator+=(const Phases& o) {
    for (size_t i = 0; i < s.size(); ++i) s[i] += o.s[i];
    return *this;
  }
};

/// Wall time of one solveSegment, the solution's destruction included, and its phases.
Phases timedSolve(const Case& c, const smoother::SmootherOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  smoother::SegmentSummary m;
  {
    smoother::SegmentSolution sol = smoother::solveSegment(*c.data, c.spec, o);
    m = sol.summary;
    benchmark::DoNotOptimize(sol);
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  Phases p;
  const double minimizer_other = m.ceres_minimizer_seconds - m.ceres_jacobian_seconds -
                                 m.ceres_residual_seconds - m.ceres_linear_solver_seconds;
  p.s = {m.build_seconds,          m.seed_seconds,           m.ceres_preprocess_seconds,
         m.ceres_jacobian_seconds, m.ceres_residual_seconds, m.ceres_linear_solver_seconds,
         minimizer_other,          m.covariance_seconds,     0.0};
  p.s.back() = wall - p.total();
  return p;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void BM_ScalingRatio(benchmark::State& state) {
  const int small_nodes = static_cast<int>(state.range(0));
  const int large_nodes = 10 * small_nodes;
  const Case& small = syntheticSegment(small_nodes);
  const Case& large = syntheticSegment(large_nodes);
  const smoother::SmootherOptions o = options(true);
  timedSolve(small, o), timedSolve(large, o);  // warm-up: first-touch of the allocator's heap
  std::vector<double> ratios, small_s, large_s;
  Phases small_phases, large_phases;  // summed over all solves, to split the ratio by phase
  for (auto _ : state) {
    std::vector<double> round;
    for (int i = 0; i < 10; ++i) {
      const Phases p = timedSolve(small, o);
      round.push_back(p.total()), small_phases += p;
    }
    const Phases l = timedSolve(large, o);
    large_phases += l;
    const double s = median(round);
    small_s.push_back(s), large_s.push_back(l.total()), ratios.push_back(l.total() / s);
  }
  state.counters["ratio_median"] = median(ratios);
  state.counters["ratio_min"] = *std::min_element(ratios.begin(), ratios.end());
  state.counters["ratio_max"] = *std::max_element(ratios.begin(), ratios.end());
  state.counters["small_median_s"] = median(small_s);
  state.counters["small_min_s"] = *std::min_element(small_s.begin(), small_s.end());
  state.counters["small_max_s"] = *std::max_element(small_s.begin(), small_s.end());
  state.counters["large_median_s"] = median(large_s);
  state.counters["large_min_s"] = *std::min_element(large_s.begin(), large_s.end());
  state.counters["large_max_s"] = *std::max_element(large_s.begin(), large_s.end());
  state.counters["rounds"] = static_cast<double>(ratios.size());
  // Per phase: the large solves' mean time in ms, and its ratio to the small solves' mean, so
  // the phases that grow faster than the node count stand out.
  const double rounds = static_cast<double>(ratios.size());
  for (size_t i = 0; i < Phases::kNames.size(); ++i) {
    const double l = large_phases.s[i] / rounds, s = small_phases.s[i] / (10 * rounds);
    state.counters[std::string("ms_") + Phases::kNames[i]] = l * 1e3;
    state.counters[std::string("x_") + Phases::kNames[i]] = s > 0 ? l / s : 0.0;
  }
}

BENCHMARK(BM_ScalingRatio)->Arg(1000)->Iterations(7)->Unit(benchmark::kSecond)->UseRealTime();
// 10 000 against 100 000 nodes: 3 rounds of ten 10k solves and one 100k solve (~2 min a round,
// plus ~5 min to simulate the 100k log once without TRAVERSE_BENCH_CACHE).
BENCHMARK(BM_ScalingRatio)->Arg(10000)->Iterations(3)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(BM_SmoothSegment)
    ->Arg(1000)
    ->Iterations(10)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_SmoothSegment)
    ->Arg(10000)
    ->Iterations(5)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_SmoothSegment)
    ->Arg(100000)
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_SmoothSegmentNoCovariance)
    ->Arg(1000)
    ->Iterations(10)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
