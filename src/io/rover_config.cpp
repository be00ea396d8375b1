// rover.yaml reading and writing (yaml-cpp). Strict: unknown keys, wrong types and values out
// of range are InputErrors naming the file, the line and the dotted key.
#include <charconv>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "io/yaml_reader.h"
#include "traverse/core/error.h"
#include "traverse/core/so3.h"
#include "traverse/io/atomic_file.h"
#include "traverse/io/input_file.h"
#include "traverse/io/rover_config.h"

namespace traverse::io {
namespace {

using detail::YamlReader;

void readGyro(const YamlReader& r, const YAML::Node& root, GyroConfig& g) {
  const YAML::Node n =
      r.section(root, "gyro",
                {"axes", "noise_rad_s", "bias_random_walk_rad_s_per_sqrt_s",
                 "initial_bias_sigma_rad_s", "rate_perturbation_rad_s2_per_sqrt_hz"});
  const std::string axes =
      r.string(n, "gyro", "axes", g.axes == GyroAxes::kThreeAxis ? "xyz" : "z");
  if (axes == "z") {
    g.axes = GyroAxes::kHeadingOnly;
  } else if (axes == "xyz") {
    g.axes = GyroAxes::kThreeAxis;
  } else {
    r.fail(n["axes"], "gyro.axes", "expected 'z' (heading only) or 'xyz', got '" + axes + "'");
  }
  g.noise_rad_s = r.number(n, "gyro", "noise_rad_s", g.noise_rad_s, 0.0, 10.0);
  g.bias_random_walk_rad_s_per_sqrt_s = r.number(n, "gyro", "bias_random_walk_rad_s_per_sqrt_s",
                                                 g.bias_random_walk_rad_s_per_sqrt_s, 0.0, 1.0);
  g.initial_bias_sigma_rad_s =
      r.number(n, "gyro", "initial_bias_sigma_rad_s", g.initial_bias_sigma_rad_s, 0.0, 1.0);
  if (n["rate_perturbation_rad_s2_per_sqrt_hz"].IsDefined())
    g.rate_perturbation_rad_s2_per_sqrt_hz =
        r.number(n, "gyro", "rate_perturbation_rad_s2_per_sqrt_hz", 0.0, 0.0, 100.0);
}

void readSensors(const YamlReader& r, const YAML::Node& root, RoverConfig& c) {
  const YAML::Node imu = r.section(root, "imu", {"mounting_rpy_rad"});
  const Vec3d imu_rpy =
      r.vec3(imu, "imu", "mounting_rpy_rad", so3::rollPitchYaw(Quatd(c.imu.R_body_imu)));
  if (imu_rpy.cwiseAbs().maxCoeff() > 2.0 * M_PI)
    r.fail(imu["mounting_rpy_rad"], "imu.mounting_rpy_rad", "angles must lie in [-2 pi, 2 pi] rad");
  if (!imu_rpy.isZero(0.0))
    c.imu.R_body_imu =
        so3::fromRollPitchYaw(imu_rpy.x(), imu_rpy.y(), imu_rpy.z()).toRotationMatrix();
  // A heading gyro measures one axis: only a turn about it (yaw) keeps that axis the body's z.
  if (c.gyro.axes != GyroAxes::kThreeAxis &&
      (c.imu.R_body_imu.col(2) - Vec3d::UnitZ()).norm() > 1e-12)
    r.fail(imu["mounting_rpy_rad"], "imu.mounting_rpy_rad",
           "tilts the IMU's z axis, but gyro.axes is 'z': a heading gyro's one axis cannot be "
           "turned into the body frame (only a yaw mounting is allowed)");
  const YAML::Node s =
      r.section(root, "sun_sensor", {"mounting_rpy_rad", "field_of_view_rad", "noise"});
  const Vec3d rpy = r.vec3(s, "sun_sensor", "mounting_rpy_rad",
                           so3::rollPitchYaw(Quatd(c.sun_sensor.R_body_sensor)));
  c.sun_sensor.R_body_sensor = so3::fromRollPitchYaw(rpy.x(), rpy.y(), rpy.z()).toRotationMatrix();
  c.sun_sensor.field_of_view_rad =
      r.number(s, "sun_sensor", "field_of_view_rad", c.sun_sensor.field_of_view_rad, 0.01, M_PI);
  c.sun_sensor.noise = r.number(s, "sun_sensor", "noise", c.sun_sensor.noise, 0.0, 1.0);

  const YAML::Node a = r.section(
      root, "accelerometer",
      {"lever_arm_m", "noise_mps2", "bias_sigma_mps2", "bias_random_walk_mps2_per_sqrt_s"});
  c.accel.lever_arm_m = r.vec3(a, "accelerometer", "lever_arm_m", c.accel.lever_arm_m);
  c.accel.noise_mps2 = r.number(a, "accelerometer", "noise_mps2", c.accel.noise_mps2, 0.0, 100.0);
  c.accel.bias_sigma_mps2 =
      r.number(a, "accelerometer", "bias_sigma_mps2", c.accel.bias_sigma_mps2, 0.0, 5.0);
  c.accel.bias_random_walk_mps2_per_sqrt_s =
      r.number(a, "accelerometer", "bias_random_walk_mps2_per_sqrt_s",
               c.accel.bias_random_walk_mps2_per_sqrt_s, 0.0, 1.0);

  const YAML::Node j = r.section(
      root, "joint_sensors",
      {"angle_noise_rad", "steering_noise_rad", "wheel_noise_rad", "rate_filter_half_window",
       "steering_filter_window_s", "suspension_filter_window_s"});
  c.joints.angle_noise_rad =
      r.number(j, "joint_sensors", "angle_noise_rad", c.joints.angle_noise_rad, 0.0, 1.0);
  if (j["steering_noise_rad"])
    c.joints.steering_noise_rad = r.number(j, "joint_sensors", "steering_noise_rad", 0.0, 0.0, 3.0);
  c.joints.wheel_noise_rad =
      r.number(j, "joint_sensors", "wheel_noise_rad", c.joints.wheel_noise_rad, 0.0, 1.0);
  c.joints.steering_filter_window_s = r.number(j, "joint_sensors", "steering_filter_window_s",
                                               c.joints.steering_filter_window_s, 0.0, 100.0);
  c.joints.suspension_filter_window_s = r.number(j, "joint_sensors", "suspension_filter_window_s",
                                                 c.joints.suspension_filter_window_s, 0.0, 100.0);
  c.joints.rate_filter_half_window = r.integer(j, "joint_sensors", "rate_filter_half_window",
                                               c.joints.rate_filter_half_window, 1, 100);
}

void readSun(const YamlReader& r, const YAML::Node& root, SunConfig& sun) {
  const YAML::Node n = r.section(root, "sun", {"direction_site", "azimuth_elevation"});
  const Vec3d d = r.vec3(n, "sun", "direction_site", sun.direction_site);
  if (d.norm() < 1e-9) r.fail(n["direction_site"], "sun.direction_site", "must not be zero");
  sun.direction_site = d.normalized();
  const YAML::Node table = n["azimuth_elevation"];
  if (!table.IsDefined() || table.IsNull()) return;
  if (!table.IsSequence() || table.size() == 0) {
    r.fail(table, "sun.azimuth_elevation", "expected a list of [t_s, azimuth_rad, elevation_rad]");
  }
  sun.azimuth_elevation.clear();
  for (size_t i = 0; i < table.size(); ++i) {
    YAML::Node row(YAML::NodeType::Map);
    row["v"] = table[i];
    const Vec3d v = r.vec3(row, "sun.azimuth_elevation", "v", Vec3d::Zero());
    if (!sun.azimuth_elevation.empty() && v.x() <= sun.azimuth_elevation.back().x()) {
      r.fail(table[i], "sun.azimuth_elevation", "times must be strictly increasing");
    }
    sun.azimuth_elevation.push_back(v);
  }
}

void readNoise(const YamlReader& r, const YAML::Node& root, RoverConfig& c) {
  const YAML::Node s = r.section(
      root, "slip_noise",
      {"longitudinal_mps", "lateral_mps", "normal_mps", "spin_rad_s", "longitudinal_per_yaw_rate_m",
       "lateral_per_yaw_rate_m", "longitudinal_per_speed", "common_longitudinal_mps",
       "common_lateral_mps", "common_yaw_rate_rad_s", "common_time_constant_s"});
  auto& sn = c.slip_noise;
  sn.longitudinal_mps =
      r.number(s, "slip_noise", "longitudinal_mps", sn.longitudinal_mps, 1e-9, 10.0);
  sn.lateral_mps = r.number(s, "slip_noise", "lateral_mps", sn.lateral_mps, 1e-9, 10.0);
  sn.normal_mps = r.number(s, "slip_noise", "normal_mps", sn.normal_mps, 1e-9, 10.0);
  sn.spin_rad_s = r.number(s, "slip_noise", "spin_rad_s", sn.spin_rad_s, 1e-9, 10.0);
  sn.longitudinal_per_yaw_rate_m = r.number(s, "slip_noise", "longitudinal_per_yaw_rate_m",
                                            sn.longitudinal_per_yaw_rate_m, 0.0, 10.0);
  sn.lateral_per_yaw_rate_m =
      r.number(s, "slip_noise", "lateral_per_yaw_rate_m", sn.lateral_per_yaw_rate_m, 0.0, 10.0);
  sn.longitudinal_per_speed =
      r.number(s, "slip_noise", "longitudinal_per_speed", sn.longitudinal_per_speed, 0.0, 10.0);
  sn.common_longitudinal_mps =
      r.number(s, "slip_noise", "common_longitudinal_mps", sn.common_longitudinal_mps, 0.0, 10.0);
  sn.common_lateral_mps =
      r.number(s, "slip_noise", "common_lateral_mps", sn.common_lateral_mps, 0.0, 10.0);
  sn.common_yaw_rate_rad_s =
      r.number(s, "slip_noise", "common_yaw_rate_rad_s", sn.common_yaw_rate_rad_s, 0.0, 10.0);
  sn.common_time_constant_s =
      r.number(s, "slip_noise", "common_time_constant_s", sn.common_time_constant_s, 1e-3, 1e6);
  if (sn.hasCommonSlip() && !(sn.common_longitudinal_mps > 0 && sn.common_lateral_mps > 0))
    r.fail(s, "slip_noise",
           "common_longitudinal_mps and common_lateral_mps must both be > 0 when either is");
  if (sn.common_yaw_rate_rad_s > 0 && !sn.hasCommonSlip())
    r.fail(s["common_yaw_rate_rad_s"], "slip_noise.common_yaw_rate_rad_s",
           "needs common_longitudinal_mps and common_lateral_mps > 0 as well");
  const YAML::Node ss = r.section(root, "skid_steer",
                                  {"icr_y_left_m", "icr_y_right_m", "icr_half_track_sigma_m",
                                   "icr_half_track_random_walk_m_per_sqrt_s"});
  if (root["skid_steer"].IsDefined() && !root["skid_steer"].IsNull()) {
    SkidSteerConfig k;
    k.icr_y_left_m = r.number(ss, "skid_steer", "icr_y_left_m", 0.0, 0.0, 100.0);
    k.icr_y_right_m = r.number(ss, "skid_steer", "icr_y_right_m", 0.0, -100.0, 0.0);
    if (ss["icr_half_track_sigma_m"].IsDefined())
      k.icr_half_track_sigma_m =
          r.number(ss, "skid_steer", "icr_half_track_sigma_m", 0.0, 0.0, 100.0);
    k.icr_half_track_random_walk_m_per_sqrt_s =
        r.number(ss, "skid_steer", "icr_half_track_random_walk_m_per_sqrt_s",
                 k.icr_half_track_random_walk_m_per_sqrt_s, 0.0, 100.0);
    if (!ss["icr_y_left_m"].IsDefined() || !ss["icr_y_right_m"].IsDefined())
      r.fail(ss, "skid_steer", "needs both icr_y_left_m and icr_y_right_m");
    c.skid_steer = k;
  }

  const YAML::Node od =
      r.section(root, "odometry",
                {"wheel_radius_scale_left", "wheel_radius_scale_right", "wheel_radius_scale_sigma",
                 "wheel_radius_scale_side_sigma", "imu_mounting_sigma_rad"});
  c.odometry.wheel_radius_scale_left = r.number(od, "odometry", "wheel_radius_scale_left",
                                                c.odometry.wheel_radius_scale_left, 0.5, 2.0);
  c.odometry.wheel_radius_scale_right = r.number(od, "odometry", "wheel_radius_scale_right",
                                                 c.odometry.wheel_radius_scale_right, 0.5, 2.0);
  c.odometry.wheel_radius_scale_sigma =
      r.number(od, "odometry", "wheel_radius_scale_sigma", 0.0, 0.0, 0.5);
  c.odometry.wheel_radius_scale_side_sigma =
      r.number(od, "odometry", "wheel_radius_scale_side_sigma", 0.0, 0.0, 0.5);
  c.odometry.imu_mounting_sigma_rad =
      r.number(od, "odometry", "imu_mounting_sigma_rad", 0.0, 0.0, 0.2);

  const YAML::Node p = r.section(
      root, "process",
      {"contact_angle_time_constant_s", "contact_angle_noise_rad_per_sqrt_s",
       "common_contact_angle_noise_rad_per_sqrt_s", "velocity_time_constant_s",
       "velocity_noise_mps2_per_sqrt_hz", "rate_time_constant_s", "rate_noise_rad_s2_per_sqrt_hz"});
  auto& pc = c.process;
  pc.contact_angle_time_constant_s = r.number(p, "process", "contact_angle_time_constant_s",
                                              pc.contact_angle_time_constant_s, 1e-3, 1e6);
  pc.contact_angle_noise_rad_per_sqrt_s =
      r.number(p, "process", "contact_angle_noise_rad_per_sqrt_s",
               pc.contact_angle_noise_rad_per_sqrt_s, 0.0, 10.0);
  if (p && p["common_contact_angle_noise_rad_per_sqrt_s"].IsDefined()) {
    pc.common_contact_angle_noise_rad_per_sqrt_s =
        r.number(p, "process", "common_contact_angle_noise_rad_per_sqrt_s", 0.0, 1e-6, 10.0);
    if (*pc.common_contact_angle_noise_rad_per_sqrt_s > pc.contact_angle_noise_rad_per_sqrt_s)
      r.fail(p["common_contact_angle_noise_rad_per_sqrt_s"],
             "process.common_contact_angle_noise_rad_per_sqrt_s",
             "must not exceed process.contact_angle_noise_rad_per_sqrt_s (the common mode of "
             "the wheels' angles cannot be noisier than each angle)");
  }
  pc.velocity_time_constant_s =
      r.number(p, "process", "velocity_time_constant_s", pc.velocity_time_constant_s, 1e-3, 1e6);
  pc.velocity_noise_mps2_per_sqrt_hz = r.number(p, "process", "velocity_noise_mps2_per_sqrt_hz",
                                                pc.velocity_noise_mps2_per_sqrt_hz, 0.0, 100.0);
  pc.rate_time_constant_s =
      r.number(p, "process", "rate_time_constant_s", pc.rate_time_constant_s, 1e-3, 1e6);
  pc.rate_noise_rad_s2_per_sqrt_hz = r.number(p, "process", "rate_noise_rad_s2_per_sqrt_hz",
                                              pc.rate_noise_rad_s2_per_sqrt_hz, 0.0, 100.0);

  const YAML::Node sm = r.section(root, "smoother", {"loss", "loss_scale"});
  if (sm["loss"].IsDefined()) {
    const std::string loss = r.string(sm, "smoother", "loss", "");
    if (loss != "huber" && loss != "cauchy" && loss != "none")
      r.fail(sm["loss"], "smoother.loss",
             "unknown robust loss '" + loss + "' (expected huber, cauchy or none)");
    c.smoother.loss = loss;
  }
  if (sm["loss_scale"].IsDefined())
    c.smoother.loss_scale = r.number(sm, "smoother", "loss_scale", 3.0, 1e-6, 1e6);
}

}  // namespace

Vec3d SunConfig::directionAt(double t) const {
  if (azimuth_elevation.empty()) return direction_site;
  auto toVec = [](double az, double el) {
    return Vec3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
  };
  const auto& tab = azimuth_elevation;
  if (t <= tab.front().x()) return toVec(tab.front().y(), tab.front().z());
  if (t >= tab.back().x()) return toVec(tab.back().y(), tab.back().z());
  size_t k = 1;
  while (tab[k].x() < t) ++k;
  const double a = (t - tab[k - 1].x()) / (tab[k].x() - tab[k - 1].x());
  const Vec3d ae = (1.0 - a) * tab[k - 1] + a * tab[k];
  return toVec(ae.y(), ae.z());
}

RoverConfig loadRoverConfig(const std::filesystem::path& yaml_file) {
  const std::string file = yaml_file.string();
  if (!std::filesystem::exists(yaml_file)) throw InputError(file, 0, "required file is missing");
  return parseRoverConfig(readInputFile(yaml_file), file);
}

namespace {

YAML::Node loadYaml(const std::string& text, const std::string& file) {
  try {
    rejectBinary(text, file);
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InputError(file, e.mark.is_null() ? 0 : e.mark.line + 1, "unreadable YAML: " + e.msg);
  }
}

RoverConfig parseRoverNode(const YAML::Node& root, const std::string& file);

/// `base` with `overlay`'s keys: mappings merged key by key, any other node replaced whole.
YAML::Node merged(const YAML::Node& base, const YAML::Node& overlay) {
  if (!base.IsMap() || !overlay.IsMap()) return YAML::Clone(overlay);
  YAML::Node out = YAML::Clone(base);
  for (const auto& kv : overlay) {
    const std::string key = kv.first.as<std::string>();
    const YAML::Node b = base[key];
    out[key] = b.IsDefined() ? merged(b, kv.second) : YAML::Clone(kv.second);
  }
  return out;
}

}  // namespace

RoverConfig loadRoverConfig(const std::filesystem::path& yaml_file,
                            const std::filesystem::path& overlay) {
  if (overlay.empty()) return loadRoverConfig(yaml_file);
  const std::string file = yaml_file.string(), ofile = overlay.string();
  if (!std::filesystem::exists(yaml_file)) throw InputError(file, 0, "required file is missing");
  if (!std::filesystem::exists(overlay)) throw InputError(ofile, 0, "overlay file not found");
  const YAML::Node base = loadYaml(readInputFile(yaml_file), file);
  const YAML::Node over = loadYaml(readInputFile(overlay), ofile);
  parseRoverNode(base, file);  // each valid on its own: errors name their own file and line
  parseRoverNode(over, ofile);
  return parseRoverNode(merged(base, over), file + " + " + ofile);
}

RoverConfig parseRoverConfig(const std::string& text, const std::string& file) {
  return parseRoverNode(loadYaml(text, file), file);
}

namespace {

RoverConfig parseRoverNode(const YAML::Node& root, const std::string& file) {
  YamlReader r(file);
  if (!root.IsMap()) throw InputError(file, 0, "expected a YAML mapping at the top level");
  r.onlyKeys(root, "",
             {"format", "name", "urdf", "joints", "turn_centre_x_m", "gravity_mps2", "gyro", "imu",
              "sun_sensor", "accelerometer", "sun", "slip_noise", "skid_steer", "odometry",
              "process", "joint_sensors", "smoother", "gps"});
  RoverConfig c;
  if (!root["format"].IsDefined()) throw InputError(file, 0, "key 'format': missing (expected 1)");
  c.format = r.integer(root, "", "format", 0, 0, 1000);
  if (c.format != 1)
    r.fail(root["format"], "format",
           "unsupported format version " + std::to_string(c.format) + " (this reader knows 1)");
  c.name = r.string(root, "", "name", c.name);
  c.urdf_file = r.string(root, "", "urdf", c.urdf_file);
  if (const YAML::Node j = root["joints"]; j.IsDefined() && !j.IsNull()) {
    if (!j.IsMap()) r.fail(j, "joints", "expected a mapping column -> URDF joint name");
    for (const auto& kv : j) {
      const std::string column = r.key(kv.first, "joints");
      if (!kv.second.IsScalar()) r.fail(kv.second, "joints." + column, "expected a string");
      for (const auto& [seen, joint] : c.joint_names) {
        if (seen == column) r.fail(kv.first, "joints." + column, "column listed twice");
      }
      c.joint_names.emplace_back(column, kv.second.as<std::string>());
    }
  }
  if (root["turn_centre_x_m"].IsDefined())
    c.turn_centre_x_m = r.number(root, "", "turn_centre_x_m", 0.0, -100.0, 100.0);
  c.gravity_mps2 = r.number(root, "", "gravity_mps2", c.gravity_mps2, 0.1, 100.0);
  readGyro(r, root, c.gyro);
  readSensors(r, root, c);
  readSun(r, root, c.sun);
  readNoise(r, root, c);
  const YAML::Node gps = r.section(root, "gps", {"antenna_body_m"});
  c.gps.antenna_body_m = r.vec3(gps, "gps", "antenna_body_m", c.gps.antenna_body_m);
  return c;
}

}  // namespace

namespace {
/// Shortest text that reads back to the same double (std::to_chars), as a plain YAML scalar.
std::string num(double v) {
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, res.ptr);
}
}  // namespace

void saveRoverConfig(const std::filesystem::path& yaml_file, const RoverConfig& c) {
  YAML::Emitter out;
  auto vec = [&](const Vec3d& v) {
    out << YAML::Flow << YAML::BeginSeq << num(v.x()) << num(v.y()) << num(v.z()) << YAML::EndSeq;
  };
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << c.format;
  out << YAML::Key << "name" << YAML::Value << c.name;
  out << YAML::Key << "urdf" << YAML::Value << c.urdf_file;
  if (!c.joint_names.empty()) {
    out << YAML::Key << "joints" << YAML::Value << YAML::BeginMap;
    for (const auto& [k, v] : c.joint_names) out << YAML::Key << k << YAML::Value << v;
    out << YAML::EndMap;
  }
  if (c.turn_centre_x_m)
    out << YAML::Key << "turn_centre_x_m" << YAML::Value << num(*c.turn_centre_x_m);
  out << YAML::Key << "gravity_mps2" << YAML::Value << num(c.gravity_mps2);
  out << YAML::Key << "gyro" << YAML::Value << YAML::BeginMap << YAML::Key << "axes" << YAML::Value
      << (c.gyro.axes == GyroAxes::kThreeAxis ? "xyz" : "z") << YAML::Key << "noise_rad_s"
      << YAML::Value << num(c.gyro.noise_rad_s) << YAML::Key << "bias_random_walk_rad_s_per_sqrt_s"
      << YAML::Value << num(c.gyro.bias_random_walk_rad_s_per_sqrt_s) << YAML::Key
      << "initial_bias_sigma_rad_s" << YAML::Value << num(c.gyro.initial_bias_sigma_rad_s);
  if (c.gyro.rate_perturbation_rad_s2_per_sqrt_hz)  // absent = the default: files unchanged
    out << YAML::Key << "rate_perturbation_rad_s2_per_sqrt_hz" << YAML::Value
        << num(*c.gyro.rate_perturbation_rad_s2_per_sqrt_hz);
  out << YAML::EndMap;
  if (c.imu.mounted()) {  // absent = identity: files unchanged
    out << YAML::Key << "imu" << YAML::Value << YAML::BeginMap << YAML::Key << "mounting_rpy_rad"
        << YAML::Value;
    vec(so3::rollPitchYaw(Quatd(c.imu.R_body_imu)));
    out << YAML::EndMap;
  }
  out << YAML::Key << "sun_sensor" << YAML::Value << YAML::BeginMap << YAML::Key
      << "mounting_rpy_rad" << YAML::Value;
  vec(so3::rollPitchYaw(Quatd(c.sun_sensor.R_body_sensor)));
  out << YAML::Key << "field_of_view_rad" << YAML::Value << num(c.sun_sensor.field_of_view_rad)
      << YAML::Key << "noise" << YAML::Value << num(c.sun_sensor.noise) << YAML::EndMap;
  out << YAML::Key << "accelerometer" << YAML::Value << YAML::BeginMap << YAML::Key << "lever_arm_m"
      << YAML::Value;
  vec(c.accel.lever_arm_m);
  out << YAML::Key << "noise_mps2" << YAML::Value << num(c.accel.noise_mps2);
  if (c.accel.bias_sigma_mps2 > 0.0)
    out << YAML::Key << "bias_sigma_mps2" << YAML::Value << num(c.accel.bias_sigma_mps2);
  if (c.accel.bias_random_walk_mps2_per_sqrt_s > 0.0)
    out << YAML::Key << "bias_random_walk_mps2_per_sqrt_s" << YAML::Value
        << num(c.accel.bias_random_walk_mps2_per_sqrt_s);
  out << YAML::EndMap;
  out << YAML::Key << "sun" << YAML::Value << YAML::BeginMap << YAML::Key << "direction_site"
      << YAML::Value;
  vec(c.sun.direction_site);
  if (!c.sun.azimuth_elevation.empty()) {
    out << YAML::Key << "azimuth_elevation" << YAML::Value << YAML::BeginSeq;
    for (const Vec3d& row : c.sun.azimuth_elevation) vec(row);
    out << YAML::EndSeq;
  }
  out << YAML::EndMap;
  const auto& s = c.slip_noise;
  out << YAML::Key << "slip_noise" << YAML::Value << YAML::BeginMap << YAML::Key
      << "longitudinal_mps" << YAML::Value << num(s.longitudinal_mps) << YAML::Key << "lateral_mps"
      << YAML::Value << num(s.lateral_mps) << YAML::Key << "normal_mps" << YAML::Value
      << num(s.normal_mps) << YAML::Key << "spin_rad_s" << YAML::Value << num(s.spin_rad_s);
  // The slip that grows with the motion: written when used (older files stay byte-identical).
  for (const auto& [key, value] :
       {std::pair{"longitudinal_per_yaw_rate_m", s.longitudinal_per_yaw_rate_m},
        std::pair{"lateral_per_yaw_rate_m", s.lateral_per_yaw_rate_m},
        std::pair{"longitudinal_per_speed", s.longitudinal_per_speed}}) {
    if (value != 0.0) out << YAML::Key << key << YAML::Value << num(value);
  }
  if (s.hasCommonSlip()) {  // the common slip state, when declared
    out << YAML::Key << "common_longitudinal_mps" << YAML::Value << num(s.common_longitudinal_mps)
        << YAML::Key << "common_lateral_mps" << YAML::Value << num(s.common_lateral_mps);
    if (s.common_yaw_rate_rad_s > 0)
      out << YAML::Key << "common_yaw_rate_rad_s" << YAML::Value << num(s.common_yaw_rate_rad_s);
    out << YAML::Key << "common_time_constant_s" << YAML::Value << num(s.common_time_constant_s);
  }
  out << YAML::EndMap;
  if (c.skid_steer) {
    out << YAML::Key << "skid_steer" << YAML::Value << YAML::BeginMap << YAML::Key << "icr_y_left_m"
        << YAML::Value << num(c.skid_steer->icr_y_left_m) << YAML::Key << "icr_y_right_m"
        << YAML::Value << num(c.skid_steer->icr_y_right_m);
    if (c.skid_steer->icr_half_track_sigma_m)
      out << YAML::Key << "icr_half_track_sigma_m" << YAML::Value
          << num(*c.skid_steer->icr_half_track_sigma_m);
    out << YAML::Key << "icr_half_track_random_walk_m_per_sqrt_s" << YAML::Value
        << num(c.skid_steer->icr_half_track_random_walk_m_per_sqrt_s) << YAML::EndMap;
  }
  if (!c.odometry.isDefault()) {  // absent = the default: existing files unchanged
    out << YAML::Key << "odometry" << YAML::Value << YAML::BeginMap << YAML::Key
        << "wheel_radius_scale_left" << YAML::Value << num(c.odometry.wheel_radius_scale_left)
        << YAML::Key << "wheel_radius_scale_right" << YAML::Value
        << num(c.odometry.wheel_radius_scale_right);
    if (c.odometry.hasScaleUncertainty()) {
      out << YAML::Key << "wheel_radius_scale_sigma" << YAML::Value
          << num(c.odometry.wheel_radius_scale_sigma) << YAML::Key
          << "wheel_radius_scale_side_sigma" << YAML::Value
          << num(c.odometry.wheel_radius_scale_side_sigma);
    }
    if (c.odometry.imu_mounting_sigma_rad > 0.0)
      out << YAML::Key << "imu_mounting_sigma_rad" << YAML::Value
          << num(c.odometry.imu_mounting_sigma_rad);
    out << YAML::EndMap;
  }
  const auto& p = c.process;
  out << YAML::Key << "process" << YAML::Value << YAML::BeginMap << YAML::Key
      << "contact_angle_time_constant_s" << YAML::Value << num(p.contact_angle_time_constant_s)
      << YAML::Key << "contact_angle_noise_rad_per_sqrt_s" << YAML::Value
      << num(p.contact_angle_noise_rad_per_sqrt_s);
  if (p.common_contact_angle_noise_rad_per_sqrt_s)  // absent = the default: files unchanged
    out << YAML::Key << "common_contact_angle_noise_rad_per_sqrt_s" << YAML::Value
        << num(*p.common_contact_angle_noise_rad_per_sqrt_s);
  out << YAML::Key << "velocity_time_constant_s" << YAML::Value << num(p.velocity_time_constant_s)
      << YAML::Key << "velocity_noise_mps2_per_sqrt_hz" << YAML::Value
      << num(p.velocity_noise_mps2_per_sqrt_hz) << YAML::Key << "rate_time_constant_s"
      << YAML::Value << num(p.rate_time_constant_s) << YAML::Key << "rate_noise_rad_s2_per_sqrt_hz"
      << YAML::Value << num(p.rate_noise_rad_s2_per_sqrt_hz) << YAML::EndMap;
  out << YAML::Key << "joint_sensors" << YAML::Value << YAML::BeginMap << YAML::Key
      << "angle_noise_rad" << YAML::Value << num(c.joints.angle_noise_rad) << YAML::Key
      << "steering_noise_rad" << YAML::Value << num(c.joints.steeringNoise()) << YAML::Key
      << "wheel_noise_rad" << YAML::Value << num(c.joints.wheel_noise_rad) << YAML::Key
      << "rate_filter_half_window" << YAML::Value << c.joints.rate_filter_half_window << YAML::Key
      << "steering_filter_window_s" << YAML::Value << num(c.joints.steering_filter_window_s)
      << YAML::Key << "suspension_filter_window_s" << YAML::Value
      << num(c.joints.suspension_filter_window_s) << YAML::EndMap;
  if (c.smoother.loss || c.smoother.loss_scale) {
    out << YAML::Key << "smoother" << YAML::Value << YAML::BeginMap;
    if (c.smoother.loss) out << YAML::Key << "loss" << YAML::Value << *c.smoother.loss;
    if (c.smoother.loss_scale)
      out << YAML::Key << "loss_scale" << YAML::Value << num(*c.smoother.loss_scale);
    out << YAML::EndMap;
  }
  if (!c.gps.antenna_body_m.isZero(0.0)) {  // absent = the default: existing files unchanged
    out << YAML::Key << "gps" << YAML::Value << YAML::BeginMap << YAML::Key << "antenna_body_m"
        << YAML::Value;
    vec(c.gps.antenna_body_m);
    out << YAML::EndMap;
  }
  out << YAML::EndMap;

  io::writeFileAtomically(
      yaml_file, std::string("# traverse rover description, log format 1 (docs/log-format.md)\n") +
                     out.c_str() + "\n");
}

}  // namespace traverse::io
