// traverse — reconstruct a rover traverse from logged telemetry (docs/cli.md).
#include <cstdlib>
#include <iostream>
#include <vector>

#include <glog/logging.h>

#include "batch.h"
#include "commands.h"
#include "traverse/core/error.h"
#include "traverse/core/memory.h"

namespace traverse::app {

std::filesystem::path datasetsDir() {
  if (const char* env = std::getenv("TRAVERSE_DATASETS_DIR")) return env;
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const auto installed = exe.parent_path().parent_path() / "share" / "traverse";
    if (std::filesystem::exists(installed / "rovers")) return installed;
  }
  return std::filesystem::path(TRAVERSE_SOURCE_DIR) / "datasets";
}

}  // namespace traverse::app

int main(int argc, char** argv) {
  using namespace traverse;
  retainFreedMemory();  // each segment reuses the previous one's pages (core/memory.h)
  // Ceres logs through glog, and a failed residual evaluation dumps whole parameter blocks as
  // warnings, several per segment. The smoother reports such a segment itself (fallback_ekf and
  // the reason), so only errors get through: one line per failed solve, on stderr, no log files.
  FLAGS_logtostderr = true;
  FLAGS_minloglevel = google::GLOG_ERROR;
  google::InitGoogleLogging(argv[0]);
  CLI::App app{"traverse: rover trajectory reconstruction (dead reckoning, EKF, batch smoother)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "traverse 0.1.0");
  app::GlobalOptions global;
  app.add_flag("-q,--quiet", global.quiet, "Print nothing but errors");
  app.fallthrough();  // global flags (--quiet) also after the subcommand
  std::vector<app::Command> commands = {
      app::addInfoCommand(app, global),     app::addEvaluateCommand(app, global),
      app::addSimulateCommand(app, global), app::addFilterCommand(app, global),
      app::addSmoothCommand(app, global),   app::addRunCommand(app, global),
      app::addBenchCommand(app, global),    app::addCalibrateCommand(app, global),
      app::addSummarizeCommand(app, global)};
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "traverse: " << e.what() << " (see --help)\n";
    return 2;
  }
  try {
    for (const app::Command& run : commands) {
      if (const int rc = run(); rc >= 0) return rc;
    }
  } catch (const InputError& e) {
    std::cerr << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "traverse: error: " << e.what() << "\n";
    return 1;
  }
  return 1;
}
