// The bundled simulated logs, read from datasets/logs/ instead of simulated again. Each is
// `traverse simulate <scenario> --seed 1` (scripts/make_datasets.sh; straight-1m is checked
// byte for byte by SimScenarios.BundledLogIsReproducible), so a test that needs only
// the log — sensors and truth.csv, not the simulator's full-rate truth vector — saves the
// simulation: 2 s for straight-1m, 41 s for multi-stop (ten times that under ASan).
#pragma once

#include <filesystem>
#include <string>

#include "support/jacobian_check.h"  // testing::sourceDir
#include "traverse/io/log_reader.h"
#include "traverse/sim/simulator.h"

namespace traverse::testing {

/// simulate(<name>, seed 1, no overrides) as the bundled log; `truth` (the full-rate samples)
/// is left empty.
inline sim::Simulation bundledSimulation(const std::string& name) {
  sim::Simulation s;
  s.log = io::readLog(std::filesystem::path(sourceDir()) / "datasets" / "logs" / name);
  return s;
}

}  // namespace traverse::testing
