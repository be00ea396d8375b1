// `traverse filter LOGDIR -o OUTDIR`: dead reckoning + forward EKF (+ metrics when truth exists).
#include <iostream>
#include <memory>

#include "commands.h"
#include "pipeline.h"

namespace traverse::app {

Command addFilterCommand(CLI::App& app, const GlobalOptions& global) {
  auto opt = std::make_shared<PipelineOptions>();
  CLI::App* cmd = app.add_subcommand(
      "filter", "Dead reckoning and the forward EKF; writes dr.*, ekf.*, segments.csv");
  addPipelineOptions(*cmd, *opt);
  return [cmd, opt, &global]() {
    if (!*cmd) return -1;
    return runLogs(*opt, global, /*smooth=*/false);
  };
}

}  // namespace traverse::app
