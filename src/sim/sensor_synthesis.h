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

/// The sun's site direction at time t (fixed, or drifting in azimuth).
Vec3d sunDirectionAt(const SensorSpec& s, double t);

/// Throws InputError when a fault names a wheel the rover does not have.
void checkFaults(const Scenario& sc, const rover::RoverGeometry& geo);

/// Applies the scenario's sensor faults (FaultSpec; all but the slip burst, which is in the
/// physics) to the synthesized streams: value faults first (gyro spikes, sun dropouts, sun
/// outliers, stuck wheel encoder), then gaps by true stamp, then clock offsets, then no_accel.
/// Truth is untouched. Random choices use streams 301.. of `seed` (the sensors' own streams are
/// unchanged).
void applyFaults(const Scenario& sc, const io::RoverConfig& config, const rover::RoverGeometry& geo,
                 const std::vector<TruthSample>& truth, io::TraverseLog& log, uint64_t seed);

}  // namespace traverse::sim
