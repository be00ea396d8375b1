// Scenario YAML (datasets/scenarios/*.yaml) with --set overrides.
#include "traverse/sim/scenario.h"

#include <cmath>
#include <set>

#include <yaml-cpp/yaml.h>

#include "io/yaml_reader.h"
#include "traverse/core/error.h"

namespace traverse::sim {
namespace {

using io::detail::YamlReader;

/// Applies "a.b.2.c=value" to the tree (creating map keys; sequence indices must exist).
void applyOverride(YAML::Node root, const std::string& assignment) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw InputError("--set", 0, "expected key=value, got '" + assignment + "'");
  }
  const std::string key = assignment.substr(0, eq);
  YAML::Node value;
  try {
    value = YAML::Load(assignment.substr(eq + 1));
  } catch (const YAML::Exception& e) {
    throw InputError("--set", 0, "key '" + key + "': unreadable value: " + e.msg);
  }
  std::vector<std::string> parts;
  for (size_t start = 0;;) {
    const size_t dot = key.find('.', start);
    parts.push_back(key.substr(start, dot - start));
    if (dot == std::string::npos) break;
    start = dot + 1;
  }
  std::vector<YAML::Node> chain{root};
  for (size_t i = 0; i + 1 < parts.size(); ++i) {
    YAML::Node cur = chain.back();
    if (cur.IsSequence()) {
      const size_t idx = std::stoul(parts[i]);
      if (idx >= cur.size()) throw InputError("--set", 0, "key '" + key + "': no item " + parts[i]);
      chain.push_back(cur[idx]);
    } else {
      chain.push_back(cur[parts[i]]);
    }
  }
  YAML::Node parent = chain.back();
  if (parent.IsSequence()) {
    const size_t idx = std::stoul(parts.back());
    if (idx >= parent.size())
      throw InputError("--set", 0, "key '" + key + "': no item " + parts.back());
    parent[idx] = value;
  } else {
    parent[parts.back()] = value;
  }
}

Leg readLeg(const YamlReader& r, const YAML::Node& n, const std::string& prefix) {
  r.onlyKeys(n, prefix,
             {"rest", "straight", "arc", "turn", "radius_m", "speed_mps", "rate_rad_s", "ramp_s",
              "steer_s", "profile"});
  Leg leg;
  int kinds = 0;
  if (n["rest"])
    leg.kind = Leg::Kind::kRest, leg.duration_s = r.number(n, prefix, "rest", 0, 0, 1e6), ++kinds;
  if (n["straight"])
    leg.kind = Leg::Kind::kStraight, leg.distance_m = r.number(n, prefix, "straight", 0, -1e4, 1e4),
    ++kinds;
  if (n["arc"])
    leg.kind = Leg::Kind::kArc, leg.distance_m = r.number(n, prefix, "arc", 0, -1e4, 1e4), ++kinds;
  if (n["turn"])
    leg.kind = Leg::Kind::kTurnInPlace, leg.angle_rad = r.number(n, prefix, "turn", 0, -1e3, 1e3),
    ++kinds;
  if (kinds != 1) r.fail(n, prefix, "a leg needs exactly one of rest, straight, arc, turn");
  leg.radius_m = r.number(n, prefix, "radius_m", leg.radius_m, -1e4, 1e4);
  if (leg.kind == Leg::Kind::kArc && std::abs(leg.radius_m) < 0.3)
    r.fail(n["radius_m"], prefix + ".radius_m", "|radius| must be ≥ 0.3 m");
  leg.speed_mps = r.number(n, prefix, "speed_mps", leg.speed_mps, 1e-4, 2.0);
  leg.rate_rad_s = r.number(n, prefix, "rate_rad_s", leg.rate_rad_s, 1e-4, 2.0);
  leg.ramp_s = r.number(n, prefix, "ramp_s", leg.ramp_s, 0.01, 1e3);
  leg.steer_s = r.number(n, prefix, "steer_s", leg.steer_s, 0.01, 1e3);
  const std::string profile = r.string(n, prefix, "profile", "ramped");
  if (profile == "smooth") {
    leg.profile = Leg::Profile::kSmooth;
  } else if (profile != "ramped") {
    r.fail(n["profile"], prefix + ".profile", "expected ramped or smooth, got '" + profile + "'");
  }
  if (n["profile"] && leg.kind == Leg::Kind::kRest)
    r.fail(n["profile"], prefix + ".profile", "a rest has no speed profile");
  return leg;
}

void readTerrain(const YamlReader& r, const YAML::Node& root, TerrainSpec& t) {
  const YAML::Node n = r.section(root, "terrain",
                                 {"type", "slope_rad", "direction_rad", "step_height_m", "step_x_m",
                                  "step_y_min_m", "step_y_max_m", "step_ramp_m", "rms_height_m",
                                  "correlation_length_m", "bumps_per_m2", "base_slope_rad"});
  t.type = r.string(n, "terrain", "type", t.type);
  if (t.type != "flat" && t.type != "plane" && t.type != "undulating" && t.type != "step" &&
      t.type != "rough") {
    r.fail(n["type"], "terrain.type",
           "expected flat, plane, undulating, step or rough, got '" + t.type + "'");
  }
  t.slope_rad = r.number(n, "terrain", "slope_rad", t.slope_rad, -1.0, 1.0);
  t.direction_rad = r.number(n, "terrain", "direction_rad", t.direction_rad, -10, 10);
  t.step_height_m = r.number(n, "terrain", "step_height_m", t.step_height_m, 0, 0.2);
  t.step_x_m = r.number(n, "terrain", "step_x_m", t.step_x_m, -1e4, 1e4);
  t.step_y_min_m = r.number(n, "terrain", "step_y_min_m", t.step_y_min_m, -1e4, 1e4);
  t.step_y_max_m = r.number(n, "terrain", "step_y_max_m", t.step_y_max_m, -1e4, 1e4);
  t.step_ramp_m = r.number(n, "terrain", "step_ramp_m", t.step_ramp_m, 0.01, 10);
  t.rms_height_m = r.number(n, "terrain", "rms_height_m", t.rms_height_m, 0, 0.2);
  t.correlation_length_m =
      r.number(n, "terrain", "correlation_length_m", t.correlation_length_m, 0.05, 100);
  t.bumps_per_m2 = r.number(n, "terrain", "bumps_per_m2", t.bumps_per_m2, 0.01, 100);
  t.base_slope_rad = r.number(n, "terrain", "base_slope_rad", t.base_slope_rad, -1.0, 1.0);
}

void readSlip(const YamlReader& r, const YAML::Node& root, SlipSpec& s) {
  const YAML::Node n =
      r.section(root, "slip",
                {"longitudinal_white_mps", "longitudinal_correlated_mps", "lateral_correlated_mps",
                 "correlation_time_s", "burst_rate_per_m", "burst_duration_s", "burst_mps"});
  s.longitudinal_white_mps =
      r.number(n, "slip", "longitudinal_white_mps", s.longitudinal_white_mps, 0, 1);
  s.longitudinal_correlated_mps =
      r.number(n, "slip", "longitudinal_correlated_mps", s.longitudinal_correlated_mps, 0, 1);
  s.lateral_correlated_mps =
      r.number(n, "slip", "lateral_correlated_mps", s.lateral_correlated_mps, 0, 1);
  s.correlation_time_s = r.number(n, "slip", "correlation_time_s", s.correlation_time_s, 0.01, 1e4);
  s.burst_rate_per_m = r.number(n, "slip", "burst_rate_per_m", s.burst_rate_per_m, 0, 100);
  s.burst_duration_s = r.number(n, "slip", "burst_duration_s", s.burst_duration_s, 0.01, 1e3);
  s.burst_mps = r.number(n, "slip", "burst_mps", s.burst_mps, -1, 1);
}

void readSensors(const YamlReader& r, const YAML::Node& root, SensorSpec& s) {
  const YAML::Node n = r.section(root, "sensors", {"gyro", "sun", "accel", "joints", "cmd", "gps"});
  const YAML::Node g = r.section(n, "gyro",
                                 {"rate_hz", "axes", "noise_rad_s", "bias_rad_s",
                                  "bias_random_walk_rad_s_per_sqrt_s", "quantum_rad_s"});
  const std::string pg = "sensors.gyro";
  s.gyro_rate_hz = r.number(g, pg, "rate_hz", s.gyro_rate_hz, 0.1, 2000);
  const std::string axes = r.string(g, pg, "axes", s.gyro_three_axis ? "xyz" : "z");
  if (axes != "z" && axes != "xyz") r.fail(g["axes"], pg + ".axes", "expected z or xyz");
  s.gyro_three_axis = axes == "xyz";
  s.gyro_noise_rad_s = r.number(g, pg, "noise_rad_s", s.gyro_noise_rad_s, 0, 1);
  s.gyro_bias_rad_s = r.vec3(g, pg, "bias_rad_s", s.gyro_bias_rad_s);
  s.gyro_bias_random_walk_rad_s_per_sqrt_s = r.number(
      g, pg, "bias_random_walk_rad_s_per_sqrt_s", s.gyro_bias_random_walk_rad_s_per_sqrt_s, 0, 1);
  s.gyro_quantum_rad_s = r.number(g, pg, "quantum_rad_s", s.gyro_quantum_rad_s, 0, 1);
  const YAML::Node u =
      r.section(n, "sun", {"rate_hz", "noise", "fov_rad", "direction_site", "azimuth_rate_rad_s"});
  const std::string pu = "sensors.sun";
  s.sun_rate_hz = r.number(u, pu, "rate_hz", s.sun_rate_hz, 0, 2000);
  s.sun_noise = r.number(u, pu, "noise", s.sun_noise, 0, 1);
  s.sun_fov_rad = r.number(u, pu, "fov_rad", s.sun_fov_rad, 0.01, M_PI);
  s.sun_direction = r.vec3(u, pu, "direction_site", s.sun_direction).normalized();
  s.sun_azimuth_rate_rad_s = r.number(u, pu, "azimuth_rate_rad_s", s.sun_azimuth_rate_rad_s, -1, 1);
  const YAML::Node a = r.section(
      n, "accel",
      {"enabled", "rate_hz", "noise_mps2", "lever_arm_m", "bias_mps2", "bias_sigma_mps2"});
  s.accel = r.boolean(a, "sensors.accel", "enabled", s.accel);
  s.accel_rate_hz = r.number(a, "sensors.accel", "rate_hz", s.accel_rate_hz, 0.1, 2000);
  s.accel_noise_mps2 = r.number(a, "sensors.accel", "noise_mps2", s.accel_noise_mps2, 0, 10);
  s.accel_lever_arm_m = r.vec3(a, "sensors.accel", "lever_arm_m", s.accel_lever_arm_m);
  s.accel_bias_mps2 = r.vec3(a, "sensors.accel", "bias_mps2", s.accel_bias_mps2);
  s.accel_bias_sigma_mps2 =
      r.number(a, "sensors.accel", "bias_sigma_mps2", s.accel_bias_sigma_mps2, 0, 5);
  const YAML::Node j = r.section(n, "joints",
                                 {"rate_hz", "angle_noise_rad", "steering_noise_rad",
                                  "angle_quantum_rad", "wheel_noise_rad", "wheel_quantum_rad"});
  const std::string pj = "sensors.joints";
  s.joints_rate_hz = r.number(j, pj, "rate_hz", s.joints_rate_hz, 0.1, 2000);
  s.joint_angle_noise_rad = r.number(j, pj, "angle_noise_rad", s.joint_angle_noise_rad, 0, 1);
  s.steering_noise_rad = r.number(j, pj, "steering_noise_rad", s.steering_noise_rad, 0, 1);
  s.joint_quantum_rad = r.number(j, pj, "angle_quantum_rad", s.joint_quantum_rad, 0, 1);
  s.wheel_angle_noise_rad = r.number(j, pj, "wheel_noise_rad", s.wheel_angle_noise_rad, 0, 1);
  s.wheel_quantum_rad = r.number(j, pj, "wheel_quantum_rad", s.wheel_quantum_rad, 0, 1);
  s.cmd = r.boolean(n, "sensors", "cmd", s.cmd);
  const YAML::Node p = r.section(n, "gps", {"rate_hz", "sigma_m", "antenna_body_m"});
  s.gps_rate_hz = r.number(p, "sensors.gps", "rate_hz", s.gps_rate_hz, 0, 2000);
  s.gps_sigma_m = r.vec3(p, "sensors.gps", "sigma_m", s.gps_sigma_m);
  if (!(s.gps_sigma_m.minCoeff() > 0))
    r.fail(p["sigma_m"], "sensors.gps.sigma_m", "every sigma must be positive");
  s.gps_antenna_body_m = r.vec3(p, "sensors.gps", "antenna_body_m", s.gps_antenna_body_m);
}

/// [t, d] → one window.
TimeWindow readWindow(const YamlReader& r, const YAML::Node& n, const std::string& key) {
  if (!n.IsSequence() || n.size() != 2) r.fail(n, key, "expected [t_start_s, duration_s]");
  double v[2];
  for (int i = 0; i < 2; ++i) {
    if (!n[i].IsScalar() || !YAML::convert<double>::decode(n[i], v[i]) || !std::isfinite(v[i]))
      r.fail(n, key, "expected [t_start_s, duration_s], two finite numbers");
  }
  if (v[1] < 0) r.fail(n, key, "a window's duration must be ≥ 0");
  return TimeWindow{v[0], v[1]};
}

/// [t, d] (one window) or [[t, d], …] (a list, possibly empty).
std::vector<TimeWindow> readWindows(const YamlReader& r, const YAML::Node& map,
                                    const std::string& prefix, const std::string& key) {
  const YAML::Node n = map[key];
  if (!n.IsDefined() || n.IsNull()) return {};
  const std::string name = YamlReader::join(prefix, key);
  if (!n.IsSequence()) r.fail(n, name, "expected [t_start_s, duration_s] or a list of them");
  if (n.size() > 0 && n[0].IsScalar()) return {readWindow(r, n, name)};
  std::vector<TimeWindow> out;
  for (size_t i = 0; i < n.size(); ++i)
    out.push_back(readWindow(r, n[i], name + "." + std::to_string(i)));
  return out;
}

void readFaults(const YamlReader& r, const YAML::Node& root, FaultSpec& f) {
  const YAML::Node n = r.section(root, "faults",
                                 {"gap", "clock_offset", "gyro_spikes", "sun_dropout",
                                  "sun_outliers", "stuck_wheel", "slip_burst", "no_accel"});
  const std::set<std::string> streams = {"gyro", "joints", "sun", "accel", "cmd"};
  const YAML::Node gap = r.section(n, "gap", streams);
  const YAML::Node clock = r.section(n, "clock_offset", streams);
  for (auto [name, s] : {std::pair<const char*, StreamFaults*>{"gyro", &f.gyro},
                         {"joints", &f.joints},
                         {"sun", &f.sun},
                         {"accel", &f.accel},
                         {"cmd", &f.cmd}}) {
    s->gaps = readWindows(r, gap, "faults.gap", name);
    s->clock_offset_s = r.number(clock, "faults.clock_offset", name, s->clock_offset_s, -1e4, 1e4);
  }
  const YAML::Node sp = r.section(n, "gyro_spikes", {"count", "magnitude_rad_s"});
  f.gyro_spike_count = r.integer(sp, "faults.gyro_spikes", "count", f.gyro_spike_count, 0, 1000000);
  f.gyro_spike_rad_s =
      r.number(sp, "faults.gyro_spikes", "magnitude_rad_s", f.gyro_spike_rad_s, 0, 1e3);
  const YAML::Node sd = r.section(n, "sun_dropout", {"windows", "fraction"});
  f.sun_dropout_windows = readWindows(r, sd, "faults.sun_dropout", "windows");
  f.sun_dropout_fraction =
      r.number(sd, "faults.sun_dropout", "fraction", f.sun_dropout_fraction, 0, 1);
  const YAML::Node so = r.section(n, "sun_outliers", {"count", "angle_rad"});
  f.sun_outlier_count =
      r.integer(so, "faults.sun_outliers", "count", f.sun_outlier_count, 0, 1000000);
  f.sun_outlier_rad = r.number(so, "faults.sun_outliers", "angle_rad", f.sun_outlier_rad, 0, M_PI);
  const YAML::Node sw = r.section(n, "stuck_wheel", {"wheel", "window"});
  f.stuck_wheel = r.integer(sw, "faults.stuck_wheel", "wheel", f.stuck_wheel, 0, 64);
  if (sw["window"] && !sw["window"].IsNull())
    f.stuck_wheel_window = readWindow(r, sw["window"], "faults.stuck_wheel.window");
  const YAML::Node sb =
      r.section(n, "slip_burst", {"window", "wheel", "longitudinal_mps", "lateral_mps"});
  if (sb["window"] && !sb["window"].IsNull())
    f.slip_burst = readWindow(r, sb["window"], "faults.slip_burst.window");
  f.slip_burst_wheel = r.integer(sb, "faults.slip_burst", "wheel", f.slip_burst_wheel, 0, 64);
  f.slip_burst_longitudinal_mps =
      r.number(sb, "faults.slip_burst", "longitudinal_mps", f.slip_burst_longitudinal_mps, -2, 2);
  f.slip_burst_lateral_mps =
      r.number(sb, "faults.slip_burst", "lateral_mps", f.slip_burst_lateral_mps, -2, 2);
  f.no_accel = r.boolean(n, "faults", "no_accel", f.no_accel);
}

}  // namespace

std::filesystem::path roverDirectory(const Scenario& sc,
                                     const std::filesystem::path& datasets_dir) {
  std::filesystem::path dir(sc.rover);
  if (!std::filesystem::exists(dir / "rover.yaml")) dir = datasets_dir / "rovers" / sc.rover;
  if (!std::filesystem::exists(dir / "rover.yaml")) {
    throw InputError(
        sc.name, 0,
        "rover '" + sc.rover + "' not found (no " + (dir / "rover.yaml").string() + ")");
  }
  return dir;
}

Scenario loadScenario(const std::string& name_or_path, const std::filesystem::path& datasets_dir,
                      const std::vector<std::string>& overrides) {
  std::filesystem::path file(name_or_path);
  if (!std::filesystem::exists(file)) file = datasets_dir / "scenarios" / (name_or_path + ".yaml");
  if (!std::filesystem::exists(file)) {
    throw InputError(name_or_path, 0, "no such scenario file, nor " + file.string());
  }
  YAML::Node root;
  try {
    root = YAML::LoadFile(file.string());
  } catch (const YAML::Exception& e) {
    throw InputError(file.string(), e.mark.is_null() ? 0 : e.mark.line + 1,
                     "unreadable YAML: " + e.msg);
  }
  for (const std::string& o : overrides) applyOverride(root, o);
  const YamlReader r(file.string());
  r.onlyKeys(root, "",
             {"name", "rover", "truth_rate_hz", "truth_output_hz", "gravity_mps2", "start",
              "terrain", "path", "slip", "sensors", "faults"});
  Scenario s;
  s.name = r.string(root, "", "name", file.stem().string());
  s.rover = r.string(root, "", "rover", s.rover);
  s.truth_rate_hz = r.number(root, "", "truth_rate_hz", s.truth_rate_hz, 200, 10000);
  s.truth_output_hz = r.number(root, "", "truth_output_hz", s.truth_output_hz, 0.1, 10000);
  s.gravity_mps2 = r.number(root, "", "gravity_mps2", s.gravity_mps2, 0.1, 100);
  const YAML::Node start = r.section(root, "start", {"x_m", "y_m", "yaw_rad"});
  s.start = Vec3d(r.number(start, "start", "x_m", 0, -1e5, 1e5),
                  r.number(start, "start", "y_m", 0, -1e5, 1e5),
                  r.number(start, "start", "yaw_rad", 0, -10, 10));
  const YAML::Node path = root["path"];
  if (!path.IsSequence() || path.size() == 0) {
    const long line = path.IsDefined() ? static_cast<long>(path.Mark().line) + 1 : 0;
    throw InputError(file.string(), line, "key 'path': expected a list of legs");
  }
  for (size_t i = 0; i < path.size(); ++i)
    s.legs.push_back(readLeg(r, path[i], "path." + std::to_string(i)));
  readTerrain(r, root, s.terrain);
  readSlip(r, root, s.slip);
  readSensors(r, root, s.sensors);
  readFaults(r, root, s.faults);
  return s;
}

}  // namespace traverse::sim
