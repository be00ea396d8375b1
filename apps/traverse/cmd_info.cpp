// `traverse info LOGDIR`: read and validate a log, print its summary.
#include <iostream>
#include <memory>

#include "commands.h"
#include "traverse/io/diagnostics.h"
#include "traverse/io/log_reader.h"

namespace traverse::app {

Command addInfoCommand(CLI::App& app, const GlobalOptions& global) {
  struct Options {
    std::string log_dir;
    bool skip_bad_rows = false;
  };
  auto opt = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "info", "Read and validate a traverse log; print streams, rates, duration, gaps");
  cmd->add_option("LOGDIR", opt->log_dir, "Log directory (docs/log-format.md)")->required();
  cmd->add_flag("--skip-bad-rows", opt->skip_bad_rows,
                "Drop malformed rows (counted and reported) instead of stopping");
  return [cmd, opt, &global]() {
    if (!*cmd) return -1;
    io::ReadReport report;
    const io::TraverseLog log =
        io::readLog(opt->log_dir, io::ReadOptions{opt->skip_bad_rows, {}}, &report);
    if (!global.quiet) std::cout << io::formatSummary(io::summarize(log));
    for (const auto& [file, n] : report.skipped_rows) {
      if (n > 0)
        std::cerr << file << ": skipped " << n << " bad row" << (n == 1 ? "" : "s") << "\n";
    }
    for (const std::string& line : io::diagnose(log).warningLines()) std::cerr << line << "\n";
    return 0;
  };
}

}  // namespace traverse::app
