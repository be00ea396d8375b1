// rover.yaml and rover.urdf reading: defaults, round trip, and one precise error per problem.
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/jacobian_check.h"
#include "traverse/core/error.h"
#include "traverse/io/rover_config.h"
#include "traverse/io/rover_description.h"

namespace traverse::io {
namespace {

using ::testing::HasSubstr;

class IoRoverConfig : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("traverse_cfg_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path write(const std::string& text) {
    const auto p = dir_ / "rover.yaml";
    std::ofstream(p) << text;
    return p;
  }
  /// Expects loading `text` to fail with the file name, `line` and `words` in the message.
  void expectError(const std::string& text, long line, const std::string& words) {
    const auto p = write(text);
    try {
      loadRoverConfig(p);
      FAIL() << "no error for:\n" << text;
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), p.string());
      EXPECT_EQ(e.line(), line) << e.what();
      EXPECT_THAT(e.what(), HasSubstr(words));
    }
  }
  std::filesystem::path dir_;
};

TEST_F(IoRoverConfig, BundledRocky7Loads) {
  const RoverConfig c =
      loadRoverConfig(testing::sourceDir() + "/datasets/rovers/rocky7/rover.yaml");
  EXPECT_EQ(c.name, "rocky7");
  EXPECT_EQ(c.gyro.axes, GyroAxes::kHeadingOnly);
  ASSERT_EQ(c.joint_names.size(), 11u);
  EXPECT_EQ(c.joint_names.front().first, "gamma0");  // document order: the joints.csv order
  EXPECT_EQ(c.joint_names.back(), std::make_pair(std::string("psi6"), std::string("wheel_6")));
  EXPECT_LT((c.sun.direction_site - Vec3d(-1, 1, 1).normalized()).norm(), 1e-15);
}

TEST_F(IoRoverConfig, CommonSlipIsReadAndNeedsBothAxes) {
  const RoverConfig c =
      loadRoverConfig(write("format: 1\nslip_noise:\n  common_longitudinal_mps: 0.01\n"
                            "  common_lateral_mps: 0.004\n  common_time_constant_s: 8\n"));
  EXPECT_EQ(c.slip_noise.common_longitudinal_mps, 0.01);
  EXPECT_EQ(c.slip_noise.common_lateral_mps, 0.004);
  EXPECT_EQ(c.slip_noise.common_time_constant_s, 8.0);
  EXPECT_TRUE(c.slip_noise.hasCommonSlip());
  EXPECT_FALSE(loadRoverConfig(write("format: 1\n")).slip_noise.hasCommonSlip());  // default off
  expectError("format: 1\nslip_noise:\n  common_longitudinal_mps: 0.01\n", 3,
              "common_longitudinal_mps and common_lateral_mps must both be > 0");
  expectError("format: 1\nslip_noise:\n  common_time_constant_s: 0\n", 3, "common_time_constant_s");
}

// slip_noise.common_yaw_rate_rad_s: c's third state, c_ω; only beside the other two; saved.
TEST_F(IoRoverConfig, CommonYawSlipIsReadSavedAndNeedsTheOtherTwo) {
  const RoverConfig c =
      loadRoverConfig(write("format: 1\nslip_noise:\n  common_longitudinal_mps: 0.01\n"
                            "  common_lateral_mps: 0.004\n  common_yaw_rate_rad_s: 0.003\n"));
  EXPECT_EQ(c.slip_noise.common_yaw_rate_rad_s, 0.003);
  EXPECT_EQ(c.slip_noise.commonSlipStates(), 3);
  const std::filesystem::path saved = dir_ / "saved.yaml";
  saveRoverConfig(saved, c);
  EXPECT_EQ(loadRoverConfig(saved).slip_noise.common_yaw_rate_rad_s, 0.003);
  const RoverConfig two =
      loadRoverConfig(write("format: 1\nslip_noise:\n  common_longitudinal_mps: 0.01\n"
                            "  common_lateral_mps: 0.004\n"));
  EXPECT_EQ(two.slip_noise.commonSlipStates(), 2);
  EXPECT_EQ(loadRoverConfig(write("format: 1\n")).slip_noise.commonSlipStates(), 0);
  expectError("format: 1\nslip_noise:\n  common_yaw_rate_rad_s: 0.003\n", 3,
              "needs common_longitudinal_mps and common_lateral_mps");
  expectError("format: 1\nslip_noise:\n  common_yaw_rate_rad_s: -1\n", 3, "common_yaw_rate_rad_s");
}

TEST_F(IoRoverConfig, GyroRatePerturbationIsOptionalAndSaved) {
  EXPECT_FALSE(loadRoverConfig(write("format: 1\n")).gyro.rate_perturbation_rad_s2_per_sqrt_hz);
  const RoverConfig c =
      loadRoverConfig(write("format: 1\ngyro:\n  rate_perturbation_rad_s2_per_sqrt_hz: 5e-4\n"));
  ASSERT_TRUE(c.gyro.rate_perturbation_rad_s2_per_sqrt_hz);
  EXPECT_EQ(*c.gyro.rate_perturbation_rad_s2_per_sqrt_hz, 5e-4);
  const std::filesystem::path saved = dir_ / "saved.yaml";
  saveRoverConfig(saved, c);
  EXPECT_EQ(*loadRoverConfig(saved).gyro.rate_perturbation_rad_s2_per_sqrt_hz, 5e-4);
  expectError("format: 1\ngyro:\n  rate_perturbation_rad_s2_per_sqrt_hz: -1\n", 3,
              "rate_perturbation_rad_s2_per_sqrt_hz");
}

// process.common_contact_angle_noise_rad_per_sqrt_s: optional (absent: each wheel's n_ξ), saved
// back, and never above n_ξ (the wheels' mean cannot be noisier than each angle) nor zero.
TEST_F(IoRoverConfig, CommonContactAngleNoiseIsOptionalBoundedAndSaved) {
  const RoverConfig d = loadRoverConfig(write("format: 1\n"));
  EXPECT_FALSE(d.process.common_contact_angle_noise_rad_per_sqrt_s);
  EXPECT_EQ(d.process.commonContactAngleNoise(), d.process.contact_angle_noise_rad_per_sqrt_s);
  const RoverConfig c =
      loadRoverConfig(write("format: 1\nprocess:\n  contact_angle_noise_rad_per_sqrt_s: 0.05\n"
                            "  common_contact_angle_noise_rad_per_sqrt_s: 0.01\n"));
  EXPECT_EQ(c.process.commonContactAngleNoise(), 0.01);
  const std::filesystem::path saved = dir_ / "saved.yaml";
  saveRoverConfig(saved, c);
  EXPECT_EQ(*loadRoverConfig(saved).process.common_contact_angle_noise_rad_per_sqrt_s, 0.01);
  expectError(
      "format: 1\nprocess:\n  contact_angle_noise_rad_per_sqrt_s: 0.05\n"
      "  common_contact_angle_noise_rad_per_sqrt_s: 0.06\n",
      4, "must not exceed process.contact_angle_noise_rad_per_sqrt_s");
  expectError("format: 1\nprocess:\n  common_contact_angle_noise_rad_per_sqrt_s: 0\n", 3,
              "common_contact_angle_noise_rad_per_sqrt_s");
}

TEST_F(IoRoverConfig, MissingKeysTakeDefaults) {
  const RoverConfig c = loadRoverConfig(write("format: 1\n"));
  const RoverConfig d;
  EXPECT_EQ(c.gravity_mps2, d.gravity_mps2);
  EXPECT_EQ(c.gyro.noise_rad_s, d.gyro.noise_rad_s);
  EXPECT_EQ(c.slip_noise.spin_rad_s, d.slip_noise.spin_rad_s);
  EXPECT_FALSE(c.turn_centre_x_m.has_value());
}

TEST_F(IoRoverConfig, SaveLoadRoundTrip) {
  RoverConfig c = loadRoverConfig(testing::sourceDir() + "/datasets/rovers/rocky7/rover.yaml");
  c.gyro.axes = GyroAxes::kThreeAxis;
  c.gravity_mps2 = 3.711;
  c.sun.azimuth_elevation = {Vec3d(0, 0.1, 0.5), Vec3d(100, 0.2, 0.6)};
  c.sun_sensor.R_body_sensor = so3::fromRollPitchYaw(0.01, -0.02, 0.3).toRotationMatrix();
  c.slip_noise.common_longitudinal_mps = 0.007;
  c.slip_noise.common_lateral_mps = 0.003;
  c.slip_noise.common_time_constant_s = 12.5;
  saveRoverConfig(dir_ / "out.yaml", c);
  const RoverConfig r = loadRoverConfig(dir_ / "out.yaml");
  EXPECT_EQ(r.gyro.axes, GyroAxes::kThreeAxis);
  EXPECT_EQ(r.gravity_mps2, 3.711);
  EXPECT_EQ(r.joint_names, c.joint_names);
  EXPECT_EQ(r.turn_centre_x_m, c.turn_centre_x_m);
  EXPECT_EQ(r.sun.azimuth_elevation.size(), 2u);
  EXPECT_LT((r.sun_sensor.R_body_sensor - c.sun_sensor.R_body_sensor).norm(), 1e-15);
  EXPECT_EQ(r.process.contact_angle_noise_rad_per_sqrt_s,
            c.process.contact_angle_noise_rad_per_sqrt_s);
  EXPECT_EQ(r.slip_noise.common_longitudinal_mps, 0.007);
  EXPECT_EQ(r.slip_noise.common_lateral_mps, 0.003);
  EXPECT_EQ(r.slip_noise.common_time_constant_s, 12.5);
}

TEST_F(IoRoverConfig, SunTableInterpolates) {
  SunConfig s;
  s.azimuth_elevation = {Vec3d(0, 0, 0), Vec3d(10, M_PI / 2, 0)};
  EXPECT_LT((s.directionAt(5) - Vec3d(std::cos(M_PI / 4), std::sin(M_PI / 4), 0)).norm(), 1e-15);
  EXPECT_LT((s.directionAt(-1) - Vec3d::UnitX()).norm(), 1e-15);
}

TEST_F(IoRoverConfig, WrongFormatVersion) {
  expectError("format: 2\n", 1, "unsupported format version 2");
}
// A list or mapping as a key is valid YAML but no key of rover.yaml: an InputError (found by
// fuzz_rover_yaml: yaml-cpp's TypedBadConversion escaped the reader and `traverse run` aborted).
TEST_F(IoRoverConfig, KeyThatIsNotText) {
  expectError("format: 1\n? [gyro]\n: 1\n", 2, "key '(top level)': a key must be plain text");
  expectError("format: 1\ngyro:\n  {a: 1}: 2\n", 3, "key 'gyro': a key must be plain text");
  expectError("format: 1\njoints:\n  [psi1]: wheel_1\n", 3,
              "key 'joints': a key must be plain text");
}
TEST_F(IoRoverConfig, MissingFormat) {
  expectError("name: x\n", 0, "'format'");
}
TEST_F(IoRoverConfig, SmootherSectionChoosesTheRobustLoss) {
  const RoverConfig c =
      loadRoverConfig(write("format: 1\nsmoother:\n  loss: cauchy\n  loss_scale: 2\n"));
  EXPECT_EQ(c.smoother.loss.value_or(""), "cauchy");
  EXPECT_EQ(c.smoother.loss_scale.value_or(0.0), 2.0);
  // Round trip, and a config without the section writes none.
  saveRoverConfig(dir_ / "saved.yaml", c);
  const RoverConfig back = loadRoverConfig(dir_ / "saved.yaml");
  EXPECT_EQ(back.smoother.loss.value_or(""), "cauchy");
  EXPECT_EQ(back.smoother.loss_scale.value_or(0.0), 2.0);
  EXPECT_FALSE(loadRoverConfig(write("format: 1\n")).smoother.loss.has_value());
}

TEST_F(IoRoverConfig, UnknownRobustLoss) {
  expectError("format: 1\nsmoother:\n  loss: tukey\n", 3, "smoother.loss");
}

TEST_F(IoRoverConfig, UnreadableYaml) {
  expectError("format: 1\ngyro: [1, 2\n", 3, "unreadable YAML");
}
TEST_F(IoRoverConfig, KeyOfWrongType) {
  expectError("format: 1\ngyro:\n  noise_rad_s: fast\n", 3,
              "'gyro.noise_rad_s': expected a number");
}
TEST_F(IoRoverConfig, ValueOutOfRange) {
  expectError("format: 1\ngravity_mps2: -9.8\n", 2, "'gravity_mps2': value -9.8 out of range");
}
TEST_F(IoRoverConfig, UnknownKey) {
  expectError("format: 1\ngyro:\n  nosie_rad_s: 0.1\n", 3, "'gyro.nosie_rad_s': unknown key");
}
TEST_F(IoRoverConfig, BadGyroAxes) {
  expectError("format: 1\ngyro: {axes: xy}\n", 2, "'gyro.axes'");
}
TEST_F(IoRoverConfig, MissingFile) {
  EXPECT_THROW(loadRoverConfig(dir_ / "nope.yaml"), InputError);
}

TEST_F(IoRoverConfig, UrdfErrorsNameTheJoint) {
  const RoverConfig c =
      loadRoverConfig(testing::sourceDir() + "/datasets/rovers/rocky7/rover.yaml");
  try {
    parseRoverGeometry("<robot name='x'><link name='base_link'/></robot>", c, "r.urdf");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(
        e.what(),
        HasSubstr("r.urdf: joint 'rocker_left' (joints.csv column 'gamma0') is not in the URDF"));
  }
  EXPECT_THROW(parseRoverGeometry("<robot", c, "r.urdf"), InputError);
}

}  // namespace
}  // namespace traverse::io
