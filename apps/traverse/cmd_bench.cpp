// `traverse bench accuracy --scenario S --runs N [--json FILE]`: Monte Carlo over seeds 1..N —
// simulate, estimate, evaluate — then mean, std, median and max of every metric.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <iostream>
#include <memory>
#include <mutex>
#include <thread>

#include "commands.h"
#include "pipeline.h"
#include "traverse/core/error.h"
#include "traverse/estimators/trajectory.h"
#include "traverse/eval/aggregate.h"
#include "traverse/eval/metrics.h"
#include "traverse/io/atomic_file.h"
#include "traverse/sim/simulator.h"

namespace traverse::app {
namespace {

struct BenchOptions {
  std::string scenario = "all";
  long runs = 20;
  std::string json, out_dir, markdown;
  std::vector<std::string> overrides;
  int jobs = 0;
  bool no_smoother = false;
  PipelineOptions pipeline;
};

eval::MetricsReport oneRun(const sim::Scenario& sc, const std::filesystem::path& rover_dir,
                           uint64_t seed, const pipeline::PipelineConfig& config) {
  const sim::Simulation s = sim::simulate(sc, rover_dir, seed);
  const pipeline::Estimates e = pipeline::estimate(s.log, config);
  std::vector<est::Trajectory> trajectories{e.dr, e.ekf.trajectory};
  if (e.ekf.rts) trajectories.push_back(*e.ekf.rts);
  if (e.smoothed) trajectories.push_back(e.smoothed->trajectory);
  const eval::TruthTrajectory truth(*s.log.truth);
  eval::MetricsReport report =
      eval::evaluateAll(sc.name + "#" + std::to_string(seed), trajectories, truth);
  setRestBiasMetric(report, e.segmentation, truth);
  // NaN or inf anywhere in what `run` would write as NAME.csv (states, σ, covariance terms):
  // a broken output must show even where the metrics do not look at it (faults, issue 15).
  for (size_t i = 0; i < trajectories.size(); ++i) {
    const io::Stream out = est::toStream(trajectories[i]);
    const auto bad = (!out.values.array().isFinite()).count() + (!out.t.array().isFinite()).count();
    report.estimators[i].metrics.set("nonfinite_values", static_cast<double>(bad));
  }
  return report;
}

}  // namespace

Command addBenchCommand(CLI::App& app, const GlobalOptions& global) {
  auto opt = std::make_shared<BenchOptions>();
  CLI::App* bench = app.add_subcommand("bench", "Benchmarks");
  bench->require_subcommand(1);
  CLI::App* cmd = bench->add_subcommand(
      "accuracy", "Monte Carlo accuracy over seeds 1..N: simulate, estimate, evaluate");
  cmd->add_option(
         "--scenario", opt->scenario,
         "Scenario name or YAML file; `all` (default): every scenario in datasets/scenarios")
      ->capture_default_str();
  cmd->add_option("--runs", opt->runs, "Number of seeds (1..N)")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--json", opt->json,
                  "Write the statistics as JSON (outputs.md); one scenario only");
  cmd->add_option("--out", opt->out_dir,
                  "Write DIR/<scenario>.json for every scenario and DIR/accuracy.md");
  cmd->add_option("--markdown", opt->markdown, "Write the Markdown tables to FILE");
  cmd->add_option("--set", opt->overrides,
                  "Override a scenario key: dotted.key=value (repeatable)");
  cmd->add_option("-j,--jobs", opt->jobs, "Parallel runs (default: all cores)");
  cmd->add_option("--attitude-model", opt->pipeline.attitude_model,
                  "gyro-driven or gyro-measurement")
      ->check(CLI::IsMember({"gyro-driven", "gyro-measurement"}));
  cmd->add_option("--velocity-model", opt->pipeline.velocity_model, "auto, perturbation or accel")
      ->check(CLI::IsMember({"auto", "perturbation", "accel"}));
  cmd->add_flag("--no-sun", opt->pipeline.no_sun, "EKF without the sun sensor");
  cmd->add_flag("--no-slip", opt->pipeline.no_slip, "EKF without the slip constraint");
  cmd->add_flag("--no-smoother", opt->no_smoother, "Dead reckoning and the EKF only");
  addSmootherOptions(*cmd, opt->pipeline);
  return [cmd, opt, &global]() {
    if (!*cmd) return -1;
    const std::filesystem::path data = datasetsDir();
    std::vector<std::string> scenarios;
    if (opt->scenario == "all") {
      for (const auto& entry : std::filesystem::directory_iterator(data / "scenarios")) {
        if (entry.path().extension() == ".yaml") scenarios.push_back(entry.path().stem().string());
      }
      std::sort(scenarios.begin(), scenarios.end());
    } else {
      scenarios.push_back(opt->scenario);
    }
    if (!opt->json.empty() && scenarios.size() > 1)
      throw InputError("--json", 0, "one scenario only; use --out DIR for several");
    pipeline::PipelineConfig config = pipelineConfig(opt->pipeline);
    config.smooth = !opt->no_smoother;
    // Runs are parallel already: one thread per run's segments unless asked otherwise.
    if (opt->pipeline.threads == 0) config.smoother.threads = 1;
    const bool progress =
        !global.quiet && isatty(STDERR_FILENO);  // a progress bar on a terminal only
    const int jobs = opt->jobs > 0
                         ? opt->jobs
                         : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    std::string markdown;
    for (size_t si = 0; si < scenarios.size(); ++si) {
      const sim::Scenario sc = sim::loadScenario(scenarios[si], data, opt->overrides);
      const std::filesystem::path rover_dir = sim::roverDirectory(sc, data);
      std::vector<eval::MetricsReport> reports(static_cast<size_t>(opt->runs));
      std::atomic<long> next{0}, done{0};
      std::mutex err_mutex;
      std::exception_ptr error;
      const auto t0 = std::chrono::steady_clock::now();
      auto bar = [&](long d) {
        const int width = 20, filled = static_cast<int>(width * d / opt->runs);
        const double s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::lock_guard<std::mutex> lock(err_mutex);
        std::cerr << "\r\033[K[" << std::string(filled, '#') << std::string(width - filled, '.')
                  << "] scenario " << si + 1 << "/" << scenarios.size() << " " << sc.name
                  << ": run " << d << "/" << opt->runs << ", " << static_cast<int>(s) << " s"
                  << std::flush;
      };
      if (progress) bar(0);
      std::vector<std::thread> pool;
      for (int j = 0; j < jobs; ++j) {
        pool.emplace_back([&] {
          for (long k; (k = next++) < opt->runs;) {
            try {
              reports[static_cast<size_t>(k)] =
                  oneRun(sc, rover_dir, static_cast<uint64_t>(k + 1), config);
            } catch (...) {
              std::lock_guard<std::mutex> lock(err_mutex);
              if (!error) error = std::current_exception();
            }
            const long d = ++done;
            if (progress) bar(d);
          }
        });
      }
      for (auto& t : pool) t.join();
      if (progress) std::cerr << "\r\033[K";
      if (error) std::rethrow_exception(error);
      const eval::AccuracyReport report = eval::aggregate(sc.name, reports);
      if (!opt->json.empty()) eval::writeAccuracyJson(opt->json, report);
      if (!opt->out_dir.empty()) {
        std::filesystem::create_directories(opt->out_dir);
        eval::writeAccuracyJson(std::filesystem::path(opt->out_dir) / (sc.name + ".json"), report);
      }
      markdown += eval::formatAccuracyMarkdown(report);
      if (!global.quiet) std::cout << eval::formatAccuracyTable(report) << std::flush;
    }
    if (!opt->out_dir.empty())
      io::writeFileAtomically(std::filesystem::path(opt->out_dir) / "accuracy.md", markdown);
    if (!opt->markdown.empty()) io::writeFileAtomically(opt->markdown, markdown);
    return 0;
  };
}

}  // namespace traverse::app
