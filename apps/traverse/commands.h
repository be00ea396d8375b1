// Subcommands of the `traverse` CLI (docs/cli.md). Each registers itself on the CLI11 app and
// returns the callback that runs it; exit codes: 0 success, 2 bad input or usage, 1 other.
#pragma once

#include <filesystem>
#include <functional>

#include <CLI/CLI.hpp>

namespace traverse::app {

struct GlobalOptions {
  bool quiet = false;
};

using Command = std::function<int()>;

/// datasets/: $TRAVERSE_DATASETS_DIR, else the installed share/traverse, else the source tree's.
std::filesystem::path datasetsDir();

Command addInfoCommand(CLI::App& app, const GlobalOptions& global);
Command addSimulateCommand(CLI::App& app, const GlobalOptions& global);
Command addFilterCommand(CLI::App& app, const GlobalOptions& global);
Command addSmoothCommand(CLI::App& app, const GlobalOptions& global);
Command addRunCommand(CLI::App& app, const GlobalOptions& global);
Command addBenchCommand(CLI::App& app, const GlobalOptions& global);
Command addEvaluateCommand(CLI::App& app, const GlobalOptions& global);
Command addCalibrateCommand(CLI::App& app, const GlobalOptions& global);

}  // namespace traverse::app
