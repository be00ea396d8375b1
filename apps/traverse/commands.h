// Subcommands of the `traverse` CLI (docs/cli.md). Each registers itself on the CLI11 app and
// returns the callback that runs it; exit codes: 0 success, 2 bad input or usage, 1 other.
#pragma once

#include <functional>

#include <CLI/CLI.hpp>

namespace traverse::app {

struct GlobalOptions {
  bool quiet = false;
};

using Command = std::function<int()>;

Command addInfoCommand(CLI::App& app, const GlobalOptions& global);

}  // namespace traverse::app
