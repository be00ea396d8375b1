// Many logs in one command (`traverse run A B C -o OUT`) and `traverse summarize OUT`
// (docs/cli.md, "Many logs"; outputs.md, "summary.csv").
//
// Each log runs as its own `traverse` process writing OUT/<log directory name>/, so one log's
// crash, refusal or memory cannot touch the others and the results cannot depend on --jobs.
// Beside the usual outputs each folder gets status.json (how the run ended, with the exact
// arguments it ran with), stdout.txt and stderr.txt (what the process printed).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "commands.h"
#include "pipeline.h"

namespace traverse::app {

struct BatchOptions {
  int jobs = 0;        ///< logs in parallel; 0: every core
  bool force = false;  ///< run logs whose outputs are up to date too
};

/// The arguments after `traverse <command> LOGDIR -o OUTDIR` that reproduce `options`: every
/// option written out, so that two runs compare equal exactly when they estimate the same way.
std::vector<std::string> pipelineArguments(const PipelineOptions& options, bool smooth);

/// Runs every log of `log_dirs` into OUTDIR/<name>/ and writes OUTDIR/summary.csv. Returns the
/// exit status: 0, or 2 when any log was refused or failed.
int runBatch(const std::vector<std::string>& log_dirs, const PipelineOptions& options,
             const BatchOptions& batch, const GlobalOptions& global, bool smooth);

/// One row of summary.csv per folder of `out_dir` that holds a status.json, in name order;
/// written atomically. Returns the number of rows. Throws InputError for an unreadable
/// status.json or metrics.json (naming it).
int writeSummary(const std::filesystem::path& out_dir);

Command addSummarizeCommand(CLI::App& app, const GlobalOptions& global);

}  // namespace traverse::app
