// rover.yaml `imu.mounting_rpy_rad`: gyro.csv and accel.csv in the IMU's own axes, turned into
// the body frame as the log is read (io::readLog), so that every estimator sees body-frame
// readings. Hand-checked values, the key's validation, and a simulated log written in a turned
// IMU frame that reads back — and estimates — as the body-frame original.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

#include "support/jacobian_check.h"
#include "traverse/core/error.h"
#include "traverse/core/so3.h"
#include "traverse/io/log_reader.h"
#include "traverse/io/log_writer.h"
#include "traverse/io/rover_config.h"
#include "traverse/pipeline/pipeline.h"
#include "traverse/sim/scenario.h"
#include "traverse/sim/simulator.h"

namespace traverse {
namespace {

const std::filesystem::path kDatasets = testing::sourceDir() + "/datasets";

std::filesystem::path scratch(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("traverse_imu_mounting_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

/// A Rocky-7 rover.yaml (three-axis gyro unless `heading`) with an imu section.
void writeRover(const std::filesystem::path& dir, const std::string& imu, bool heading = false) {
  std::filesystem::copy_file(kDatasets / "rovers/rocky7/rover.urdf", dir / "rover.urdf",
                             std::filesystem::copy_options::overwrite_existing);
  std::ofstream(dir / "rover.yaml")
      << "format: 1\nurdf: rover.urdf\ngyro:\n  axes: " << (heading ? "z" : "xyz") << "\n"
      << imu;
}

// The IMU of the Pathfinder importer's convention (x forward, y right, z down): a roll of π
// from the body (x forward, y left, z up). A reading (a, b, c) in the IMU is (a, −b, −c) in the
// body: a rover at rest reads (0, 0, −9.8) in the IMU and (0, 0, +9.8) in the body.
TEST(IoImuMounting, TurnsTheReadingsIntoTheBodyFrameHandChecked) {
  const auto dir = scratch("hand");
  writeRover(dir, "imu:\n  mounting_rpy_rad: [3.141592653589793, 0, 0]\n");
  const io::RoverConfig c = io::loadRoverConfig(dir / "rover.yaml");
  ASSERT_TRUE(c.imu.mounted());
  EXPECT_LT((c.imu.R_body_imu - Vec3d(1, -1, -1).asDiagonal().toDenseMatrix()).norm(), 1e-14);
  std::ofstream(dir / "gyro.csv") << "t,wx,wy,wz\n0,0.1,0.2,0.3\n0.1,0.1,0.2,0.3\n";
  std::ofstream(dir / "accel.csv") << "t,ax,ay,az\n0,0.5,-0.25,-9.8\n0.1,0.5,-0.25,-9.8\n";
  // (No joints map in this rover.yaml: the columns are the URDF's movable joints.)
  std::ofstream(dir / "joints.csv")
      << "t,rocker_left,steer_left,wheel_1,bogie_left,wheel_2,wheel_3,steer_right,wheel_4,"
         "bogie_right,wheel_5,wheel_6\n0,0,0,0,0,0,0,0,0,0,0,0\n0.1,0,0,0,0,0,0,0,0,0,0,0\n";
  const io::TraverseLog log = io::readLog(dir);
  EXPECT_NEAR(log.gyro.values(1, 0), 0.1, 1e-14);
  EXPECT_NEAR(log.gyro.values(1, 1), -0.2, 1e-14);
  EXPECT_NEAR(log.gyro.values(1, 2), -0.3, 1e-14);
  ASSERT_TRUE(log.accel.has_value());
  EXPECT_NEAR(log.accel->values(0, 0), 0.5, 1e-14);
  EXPECT_NEAR(log.accel->values(0, 1), 0.25, 1e-14);
  EXPECT_NEAR(log.accel->values(0, 2), 9.8, 1e-14);
  // The readings are the body's now: the log's config says identity, so nothing turns them
  // twice, and a log written back from it carries no imu key.
  EXPECT_FALSE(log.config.imu.mounted());
  const auto back = scratch("hand_back");
  io::writeLog(back, log);
  std::ifstream in(back / "rover.yaml");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text.find("imu"), std::string::npos);
  EXPECT_EQ(io::readLog(back).accel->values, log.accel->values);
  std::filesystem::remove_all(dir);
  std::filesystem::remove_all(back);
}

TEST(IoImuMounting, KeyIsWrittenBackReadAndValidated) {
  const auto dir = scratch("keys");
  writeRover(dir, "imu:\n  mounting_rpy_rad: [0.01, -0.02, 1.5]\n");
  const io::RoverConfig c = io::loadRoverConfig(dir / "rover.yaml");
  const Mat3d R = so3::fromRollPitchYaw(0.01, -0.02, 1.5).toRotationMatrix();
  EXPECT_LT((c.imu.R_body_imu - R).norm(), 1e-14);
  io::saveRoverConfig(dir / "again.yaml", c);
  EXPECT_LT((io::loadRoverConfig(dir / "again.yaml").imu.R_body_imu - R).norm(), 1e-14);
  // Absent or zero: identity, and not written.
  writeRover(dir, "");
  const io::RoverConfig none = io::loadRoverConfig(dir / "rover.yaml");
  EXPECT_FALSE(none.imu.mounted());
  io::saveRoverConfig(dir / "none.yaml", none);
  std::ifstream in(dir / "none.yaml");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text.find("imu"), std::string::npos);
  // One clear line naming the key for: a heading gyro under a tilted IMU, a bad list, an
  // unknown key. A heading gyro under a yawed IMU is fine (its wz is the body's).
  const auto expectError = [&](const std::string& imu, bool heading, const std::string& what) {
    writeRover(dir, imu, heading);
    try {
      io::loadRoverConfig(dir / "rover.yaml");
      ADD_FAILURE() << "accepted: " << imu;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  expectError("imu:\n  mounting_rpy_rad: [0.1, 0, 0]\n", true, "imu.mounting_rpy_rad");
  expectError("imu:\n  mounting_rpy_rad: [0.1, 0]\n", false, "imu.mounting_rpy_rad");
  expectError("imu:\n  mounting_rpy_rad: [0, 0, 9]\n", false, "imu.mounting_rpy_rad");
  expectError("imu:\n  lever_arm_m: [0, 0, 0]\n", false, "lever_arm_m");
  writeRover(dir, "imu:\n  mounting_rpy_rad: [0, 0, 0.5]\n", true);
  EXPECT_TRUE(io::loadRoverConfig(dir / "rover.yaml").imu.mounted());
  std::filesystem::remove_all(dir);
}

// A simulated log (three-axis gyro) written with its gyro and accelerometer readings in an IMU
// frame turned by R (f_imu = Rᵀ f_body) and rover.yaml declaring R: it reads back as the
// original to rounding, and the EKF and the smoother estimate the same trajectory.
TEST(IoImuMounting, ATurnedImuLogEstimatesAsTheBodyFrameLog) {
  const sim::Scenario sc = sim::loadScenario("straight-1m", kDatasets, {"sensors.gyro.axes=xyz"});
  const sim::Simulation s = sim::simulate(sc, sim::roverDirectory(sc, kDatasets), 2);
  const Mat3d R = so3::fromRollPitchYaw(0.3, -0.2, 2.0).toRotationMatrix();
  io::TraverseLog turned = s.log;
  turned.config.imu.R_body_imu = R;
  for (io::Stream* st : {&turned.gyro, &*turned.accel})
    st->values.leftCols<3>() = (st->values.leftCols<3>() * R).eval();  // rows: (Rᵀ f)ᵀ = fᵀ R
  const auto original_dir = scratch("sim_body"), turned_dir = scratch("sim_imu");
  io::writeLog(original_dir, s.log);
  io::writeLog(turned_dir, turned);
  const io::TraverseLog a = io::readLog(original_dir), b = io::readLog(turned_dir);
  EXPECT_LT((a.gyro.values - b.gyro.values).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_LT((a.accel->values - b.accel->values).cwiseAbs().maxCoeff(), 1e-14);
  pipeline::PipelineConfig config;
  config.smooth = true;
  const pipeline::Estimates ea = pipeline::estimate(a, config), eb = pipeline::estimate(b, config);
  ASSERT_TRUE(ea.smoothed && eb.smoothed);
  for (const auto& [x, y] : {std::pair{&ea.ekf.trajectory, &eb.ekf.trajectory},
                             std::pair{&ea.smoothed->trajectory, &eb.smoothed->trajectory}}) {
    ASSERT_EQ(x->nodes.size(), y->nodes.size());
    EXPECT_LT((x->nodes.back().p_site - y->nodes.back().p_site).norm(), 1e-6);
    EXPECT_LT(so3::boxminus(x->nodes.back().q_site_body, y->nodes.back().q_site_body).norm(), 1e-6);
  }
  std::filesystem::remove_all(original_dir);
  std::filesystem::remove_all(turned_dir);
}

}  // namespace
}  // namespace traverse
