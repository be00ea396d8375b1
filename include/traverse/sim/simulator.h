// The traverse simulator: a rover (any URDF: rocker-bogie, rigid, …) driven along a scenario's path
// over its terrain, with ground truth at a high internal rate and every sensor sampled from it at
// its own rate through the same measurement models the estimators use (docs/simulator.md).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "traverse/io/log.h"
#include "traverse/rover/kinematics.h"
#include "traverse/sim/contact_solver.h"
#include "traverse/sim/scenario.h"

namespace traverse::sim {

/// Ground truth at one internal time step.
struct TruthSample {
  double t = 0.0;
  Vec3d p_site = Vec3d::Zero();  ///< body origin
  Quatd q_site_body = Quatd::Identity();
  Vec3d v_body = Vec3d::Zero(), w_body = Vec3d::Zero();
  Vec3d a_body = Vec3d::Zero(), w_dot_body = Vec3d::Zero();  ///< body-frame derivatives of v, ω
  rover::JointVectord joints;  ///< every coordinate, in RoverGeometry::coords order
  rover::JointVectord joint_rates;
  rover::WheelVectord xi;                     ///< contact angles, one per wheel
  rover::WheelVectord slip_longitudinal_mps;  ///< injected, per wheel
  Vec3d gyro_bias = Vec3d::Zero();
  Twistd cmd = Twistd::Zero();  ///< commanded body twist (path without slip)
  bool moving = false;          ///< inside a motion leg (not rest or steering)
  double progress = 0.0;        ///< the leg's |speed| / cruise (PathSample), which scales slip
};

struct Simulation {
  std::vector<TruthSample> truth;  ///< at Scenario::truth_rate_hz
  io::TraverseLog log;             ///< sensors at their rates, truth.csv at truth_output_hz
};

/// Runs a scenario. `rover_dir` holds rover.urdf and rover.yaml; the log's rover.yaml is that
/// file with the scenario's sensor set-up and noise written in. Same seed → same numbers.
Simulation simulate(const Scenario& scenario, const std::filesystem::path& rover_dir,
                    uint64_t seed);

/// `clean` (simulate() of a scenario without sensor faults) with `scenario`'s sensor faults
/// applied as simulate() applies them — every fault but the slip burst, which is in the physics
/// and is refused here (std::invalid_argument). With the same seed and otherwise the same
/// scenario, the result equals simulate(scenario, …) (tests/sim_faults_test.cpp checks it):
/// fault studies then pay for the physics once.
Simulation withSensorFaults(Simulation clean, const Scenario& scenario, uint64_t seed);

/// Truth interpolated at time t (linear; slerp for attitude; clamped at the ends).
TruthSample interpolateTruth(const std::vector<TruthSample>& truth, double t);

/// The reference path alone (turn-centre point, heading, steering, commanded rates) sampled at
/// the internal rate; used by simulate() and by tests.
struct PathSample {
  double t = 0.0;
  Vec2d centre = Vec2d::Zero();  ///< turn-centre point, site x, y
  double yaw = 0.0;
  rover::JointVectord steering;  ///< steering angles, one per steering coordinate
  double speed_mps = 0.0;        ///< commanded speed of the turn-centre point
  double yaw_rate_rad_s = 0.0;   ///< commanded yaw rate
  double progress = 0.0;         ///< |speed| / cruise in [0, 1] (0 at rest)
  bool moving = false;
};

/// Speed profile of one motion leg moving `amount` (> 0: metres or radians) at cruise speed
/// `cruise`: position(t) in [0, amount] over [0, duration()] and its exact derivative rate(t).
/// kRamped: quintic ramps of `ramp` s and a cruise phase (cruise lowered if the leg is too short
/// to reach it). kSmooth: rate = (amount/T)·30u²(1−u)², u = t/T, position = amount·smoothstep(u),
/// T = amount·(15/8)/cruise so the peak (u = ½) is the cruise speed; `ramp` is unused.
struct SpeedProfile {
  SpeedProfile(Leg::Profile kind, double amount, double cruise, double ramp);
  double duration() const;
  double rate(double t) const;
  double position(double t) const;
  Leg::Profile kind;
  double amount, cruise, ramp, cruise_time;
};

std::vector<PathSample> samplePath(const Scenario& scenario, const rover::RoverGeometry& geometry);

}  // namespace traverse::sim
