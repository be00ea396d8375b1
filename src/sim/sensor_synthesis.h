// Sensor streams sampled from the simulator's truth through the shared measurement models.
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include "traverse/io/log.h"
#include "traverse/sim/simulator.h"

namespace traverse::sim {

io::TraverseLog synthesizeLog(const Scenario& sc, io::RoverConfig config,
                              const rover::RoverGeometry& geo,
                              const std::filesystem::path& rover_dir,
                              const std::vector<TruthSample>& truth, uint64_t seed);

}  // namespace traverse::sim
