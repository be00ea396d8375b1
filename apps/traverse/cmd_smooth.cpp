// `traverse smooth LOGDIR -o OUTDIR`: dead reckoning, the EKF and the per-segment batch
// smoother; `traverse run LOGDIR -o OUTDIR`: the same, the main job (evaluation when the log
// has truth, and the report once it exists).
#include <memory>

#include "commands.h"
#include "pipeline.h"

namespace traverse::app {
namespace {

Command addSmoothingCommand(CLI::App& app, const GlobalOptions& global, const char* name,
                            const char* help) {
  auto opt = std::make_shared<PipelineOptions>();
  opt->command_name = name;
  CLI::App* cmd = app.add_subcommand(name, help);
  addPipelineOptions(*cmd, *opt);
  addSmootherOptions(*cmd, *opt);
  return [cmd, opt, &global]() {
    if (!*cmd) return -1;
    return runLogs(*opt, global, /*smooth=*/true);
  };
}

}  // namespace

Command addSmoothCommand(CLI::App& app, const GlobalOptions& global) {
  return addSmoothingCommand(
      app, global, "smooth",
      "Dead reckoning, EKF and the per-segment batch smoother; writes dr.*, ekf.*, smoothed.*, "
      "segments.csv (and metrics.json when the log has truth)");
}

Command addRunCommand(CLI::App& app, const GlobalOptions& global) {
  return addSmoothingCommand(
      app, global, "run",
      "Everything: the three estimators and, when the log has truth, their evaluation");
}

}  // namespace traverse::app
