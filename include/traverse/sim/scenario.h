// A simulation scenario (datasets/scenarios/*.yaml): rover, terrain, path, slip, sensors.
// Every default is here; docs/simulator.md lists them. Any key can be overridden from the
// command line with --set dotted.key=value (sequence items by index: path.legs.1.distance_m=2).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "traverse/core/types.h"

namespace traverse::sim {

struct Leg {
  enum class Kind { kRest, kStraight, kArc, kTurnInPlace };
  /// Speed profile of a motion leg: kRamped = quintic ramps of `ramp_s` and a cruise phase;
  /// kSmooth = one bump 30u²(1−u)² over the whole leg (no cruise), peaking at the cruise speed.
  enum class Profile { kRamped, kSmooth };
  Kind kind = Kind::kRest;
  double duration_s = 10.0;  ///< rest
  double distance_m = 1.0;   ///< straight, arc (path length of the turn centre point)
  double radius_m = 2.0;     ///< arc: turn radius of the turn-centre point, + = left
  double angle_rad = 0.0;    ///< turn in place: + = counter-clockwise
  double speed_mps = 0.05;   ///< cruise speed (straight, arc)
  double rate_rad_s = 0.1;   ///< cruise yaw rate (turn in place)
  double ramp_s = 2.0;       ///< quintic speed ramps at start and end
  double steer_s = 1.0;      ///< time to steer the front wheels before moving (if they must)
  Profile profile = Profile::kRamped;
};

struct TerrainSpec {
  std::string type = "flat";                    ///< flat | plane | undulating | step | rough
  double slope_rad = 0.1, direction_rad = 0.0;  ///< plane
  double step_height_m = 0.06, step_x_m = 0.5, step_y_min_m = -1.0,  ///< step (brick, K §4.2)
      step_y_max_m = 0.0, step_ramp_m = 0.15;
  double rms_height_m = 0.02, correlation_length_m = 0.5;  ///< rough
  double bumps_per_m2 = 2.0;
  double base_slope_rad = 0.0;  ///< rough: on top of a plane rising along +x
};

struct SlipSpec {
  double longitudinal_white_mps = 0.0;       ///< per wheel, white, scaled by |speed|/cruise
  double longitudinal_correlated_mps = 0.0;  ///< per wheel, first-order Gauss–Markov
  double lateral_correlated_mps = 0.0;  ///< body transverse slip (moves the rover off its path)
  double correlation_time_s = 5.0;
  double burst_rate_per_m = 0.0;  ///< slip bursts per metre driven (all wheels)
  double burst_duration_s = 2.0;
  double burst_mps = 0.02;  ///< longitudinal slip during a burst
};

struct SensorSpec {
  double gyro_rate_hz = 20.0;
  bool gyro_three_axis = false;
  double gyro_noise_rad_s = 0.0031;
  Vec3d gyro_bias_rad_s = Vec3d(0.0, 0.0, 0.002);
  double gyro_bias_random_walk_rad_s_per_sqrt_s = 0.0;
  double gyro_quantum_rad_s = 0.0;
  double sun_rate_hz = 1.0;
  double sun_noise = 0.005;
  double sun_fov_rad = 2.7925268;
  Vec3d sun_direction = Vec3d(-1.0, 1.0, 1.0).normalized();
  double sun_azimuth_rate_rad_s = 0.0;  ///< moving sun (azimuth drift), 0 = fixed
  bool accel = true;
  double accel_rate_hz = 20.0;
  double accel_noise_mps2 = 0.01;
  Vec3d accel_lever_arm_m = Vec3d(0.0, 0.0, 0.05);
  /// A constant accelerometer bias added to every reading (body, m/s²), and the 1σ the log's
  /// rover.yaml declares for it (accelerometer.bias_sigma_mps2; 0: none declared, no states).
  Vec3d accel_bias_mps2 = Vec3d::Zero();
  double accel_bias_sigma_mps2 = 0.0;
  double joints_rate_hz = 20.0;
  double joint_angle_noise_rad = 0.0;  ///< suspension potentiometers γ
  double steering_noise_rad = 0.0;     ///< steering potentiometers λ
  double joint_quantum_rad = 0.0;      ///< γ, λ quantisation
  double wheel_angle_noise_rad = 0.0;  ///< drive encoders ψ
  double wheel_quantum_rad = 0.0;
  bool cmd = true;
  /// gps.csv, position-only truth of an antenna at gps_antenna_body_m: the true antenna
  /// position plus white noise of 1σ gps_sigma_m per site axis. 0 Hz: no gps.csv.
  double gps_rate_hz = 0.0;
  Vec3d gps_sigma_m = Vec3d(0.02, 0.02, 0.04);
  Vec3d gps_antenna_body_m = Vec3d::Zero();
};

/// A time window [t_start_s, t_start_s + duration_s) on the simulation clock; YAML [t, d].
struct TimeWindow {
  double t_start_s = 0.0;
  double duration_s = 0.0;
  bool contains(double t) const { return t >= t_start_s && t < t_start_s + duration_s; }
  bool empty() const { return duration_s <= 0.0; }
};

/// Faults of one written sensor stream.
struct StreamFaults {
  std::vector<TimeWindow> gaps;  ///< rows stamped (true time) inside a window are not written
  double clock_offset_s = 0.0;   ///< added to every stamp of the stream as written
};

/// Injected faults (issue 15), all off by default. Every fault but the slip burst is applied to
/// the sensor streams after the simulation (truth untouched); the slip burst is in the physics.
/// Random choices (spike and outlier rows, dropped sun readings) come from their own random
/// streams of the run's seed, so the rest of the log is unchanged (docs/simulator.md).
struct FaultSpec {
  StreamFaults gyro, joints, sun, accel, cmd;
  int gyro_spike_count = 0;       ///< single-sample glitches at random rows
  double gyro_spike_rad_s = 0.5;  ///< added with a random sign (every column of the row)
  std::vector<TimeWindow> sun_dropout_windows;  ///< readings marked invalid (s1 = s2 = 0)
  double sun_dropout_fraction = 0.0;  ///< … and each other reading with this probability
  int sun_outlier_count = 0;          ///< valid readings replaced by a wrong direction
  double sun_outlier_rad = 0.5;       ///< the sun rotated by ± this about the site vertical
  int stuck_wheel = 0;                ///< wheel 1..N whose drive encoder sticks; 0 = none
  TimeWindow stuck_wheel_window;      ///< it reads constant here, then counts on from there
  TimeWindow slip_burst;              ///< extra slip in the physics (true motion)
  int slip_burst_wheel = 0;           ///< 1..N: that wheel only; 0 = every wheel
  double slip_burst_longitudinal_mps = -0.02;  ///< < 0: the wheels turn more than the rover moves
  double slip_burst_lateral_mps = 0.0;         ///< body transverse velocity (+ = left)
  bool no_accel = false;                       ///< accel.csv not written
};

struct Scenario {
  std::string name;
  std::string rover = "rocky7";   ///< datasets/rovers/<rover>/ or a directory path
  double truth_rate_hz = 200.0;   ///< internal simulation rate (≥ 200 Hz)
  double truth_output_hz = 20.0;  ///< rate of truth.csv
  double gravity_mps2 = 9.80665;
  Vec3d start = Vec3d::Zero();  ///< x, y (m) of the turn-centre point, yaw (rad)
  std::vector<Leg> legs;
  TerrainSpec terrain;
  SlipSpec slip;
  SensorSpec sensors;
  FaultSpec faults;
};

/// The rover directory a scenario names: a directory path, or datasets/rovers/<rover>. Throws
/// InputError when neither holds a rover.yaml.
std::filesystem::path roverDirectory(const Scenario& scenario,
                                     const std::filesystem::path& datasets_dir);

/// Loads a scenario by name (datasets/scenarios/<name>.yaml under `datasets_dir`) or path,
/// applying `overrides` ("dotted.key=value"). Errors are InputErrors naming file, line, key.
Scenario loadScenario(const std::string& name_or_path, const std::filesystem::path& datasets_dir,
                      const std::vector<std::string>& overrides = {});

}  // namespace traverse::sim
