// `traverse simulate SCENARIO -o LOGDIR [--seed N] [--set key=value ...]`
#include <iostream>
#include <memory>

#include "commands.h"
#include "traverse/core/error.h"
#include "traverse/io/log_writer.h"
#include "traverse/sim/simulator.h"

namespace traverse::app {

Command addSimulateCommand(CLI::App& app, const GlobalOptions& global) {
  struct Options {
    std::string scenario, out;
    uint64_t seed = 1;
    std::vector<std::string> overrides;
  };
  auto opt = std::make_shared<Options>();
  CLI::App* cmd =
      app.add_subcommand("simulate", "Simulate a scenario and write a traverse log with truth.csv");
  cmd->add_option("SCENARIO", opt->scenario,
                  "Scenario name (datasets/scenarios/NAME.yaml) or YAML file")
      ->required();
  cmd->add_option("-o,--output", opt->out, "Log directory to write")->required();
  cmd->add_option("--seed", opt->seed, "Random seed (same seed, same bytes)")
      ->capture_default_str();
  cmd->add_option("--set", opt->overrides,
                  "Override a scenario key: dotted.key=value (repeatable)");
  return [cmd, opt, &global]() {
    if (!*cmd) return -1;
    const std::filesystem::path data = datasetsDir();
    const sim::Scenario sc = sim::loadScenario(opt->scenario, data, opt->overrides);
    const std::filesystem::path rover_dir = sim::roverDirectory(sc, data);
    const sim::Simulation result = sim::simulate(sc, rover_dir, opt->seed);
    io::writeLog(opt->out, result.log);
    if (!global.quiet) {
      const auto& last = result.truth.back();
      std::cout << "simulated " << sc.name << " (seed " << opt->seed << "): " << last.t << " s, "
                << result.truth.size() << " truth samples, final position ("
                << last.p_site.transpose() << ") m -> " << opt->out << "\n";
    }
    return 0;
  };
}

}  // namespace traverse::app
