// Position-only truth in the log: gps.csv read with the log, its bad input as one
// FILE:LINE: problem, and rover.yaml's gps.antenna_body_m (docs/log-format.md).
#include <cstdlib>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include "traverse/core/error.h"
#include "traverse/io/log_reader.h"
#include "traverse/io/rover_config.h"

namespace traverse::io {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

fs::path straightLog() {
  const char* env = std::getenv("TRAVERSE_SOURCE_DIR");
  return fs::path(env != nullptr ? env : TRAVERSE_SOURCE_DIR) / "datasets" / "logs" / "straight-1m";
}

class IoGps : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("traverse_gps_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::copy(straightLog(), dir_);
    fs::remove(dir_ / "truth.csv");
  }
  void TearDown() override { fs::remove_all(dir_); }

  void write(const std::string& name, const std::string& text) {
    std::ofstream(dir_ / name, std::ios::binary) << text;
  }
  void appendYaml(const std::string& text) {
    std::ofstream(dir_ / "rover.yaml", std::ios::app) << text;
  }
  /// readLog must fail with exactly FILE:LINE and a message holding `words`.
  void expectError(const std::string& file, long line, const std::string& words) {
    try {
      readLog(dir_);
      FAIL() << "no error";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), (dir_ / file).string());
      EXPECT_EQ(e.line(), line) << e.what();
      EXPECT_THAT(e.message(), HasSubstr(words)) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    }
  }

  fs::path dir_;
};

TEST_F(IoGps, ReadWithTheLogAndTheLeverArm) {
  write("gps.csv", "t,x,y,z,sx,sy,sz\n0.5,1,2,3,0.01,0.02,0.03\n1,1.5,2,3,0.01,0.02,0.03\n");
  appendYaml("gps:\n  antenna_body_m: [0.1, -0.2, 0.8]\n");
  const TraverseLog log = readLog(dir_);
  ASSERT_TRUE(log.gps.has_value());
  EXPECT_FALSE(log.truth.has_value());
  EXPECT_EQ(log.gps->size(), 2);
  EXPECT_EQ(log.gps->channel("x")[1], 1.5);
  EXPECT_EQ(log.gps->channel("sz")[0], 0.03);
  EXPECT_EQ(log.config.gps.antenna_body_m, Vec3d(0.1, -0.2, 0.8));
  const LogSummary s = summarize(log);
  ASSERT_FALSE(s.streams.empty());
  EXPECT_EQ(s.streams.back().name, "gps");
  EXPECT_THAT(formatSummary(s), HasSubstr("position-only truth"));
}

TEST_F(IoGps, LeverArmDefaultsToZeroAndRoundTrips) {
  EXPECT_EQ(loadRoverConfig(dir_ / "rover.yaml").gps.antenna_body_m, Vec3d::Zero());
  RoverConfig c = loadRoverConfig(dir_ / "rover.yaml");
  c.gps.antenna_body_m = Vec3d(0.25, 0, 1.5);
  saveRoverConfig(dir_ / "again.yaml", c);
  EXPECT_EQ(loadRoverConfig(dir_ / "again.yaml").gps.antenna_body_m, Vec3d(0.25, 0, 1.5));
}

TEST_F(IoGps, ZeroSigmaIsOutOfRange) {
  write("gps.csv", "t,x,y,z,sx,sy,sz\n0,0,0,0,0.01,0.01,0.01\n0.1,0,0,0,0,0.01,0.01\n");
  expectError("gps.csv", 3, "value 0 in column 'sx' out of physical range");
}

TEST_F(IoGps, NegativeSigmaIsOutOfRange) {
  write("gps.csv", "t,x,y,z,sx,sy,sz\n0,0,0,0,0.01,0.01,-0.5\n");
  expectError("gps.csv", 2, "column 'sz' out of physical range");
}

TEST_F(IoGps, MissingSigmaColumn) {
  write("gps.csv", "t,x,y,z,sx,sy\n0,0,0,0,0.01,0.01\n");
  expectError("gps.csv", 1, "missing column 'sz'");
}

TEST_F(IoGps, NonIncreasingTime) {
  write("gps.csv", "t,x,y,z,sx,sy,sz\n1,0,0,0,1,1,1\n0.5,0,0,0,1,1,1\n");
  expectError("gps.csv", 3, "non-increasing time");
}

TEST_F(IoGps, NanPosition) {
  write("gps.csv", "t,x,y,z,sx,sy,sz\n0,nan,0,0,1,1,1\n");
  expectError("gps.csv", 2, "NaN in column 'x'");
}

TEST_F(IoGps, LeverArmOfTwoNumbers) {
  write("gps.csv", "t,x,y,z,sx,sy,sz\n0,0,0,0,1,1,1\n");
  appendYaml("gps:\n  antenna_body_m: [0.1, 0.2]\n");
  try {
    readLog(dir_);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), (dir_ / "rover.yaml").string());
    EXPECT_GT(e.line(), 0);
    EXPECT_THAT(e.message(), HasSubstr("key 'gps.antenna_body_m': expected a list of 3 numbers"));
  }
}

TEST_F(IoGps, UnknownGpsKey) {
  appendYaml("gps:\n  antenna_m: [0, 0, 0]\n");
  try {
    readLog(dir_);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.message(), HasSubstr("key 'gps.antenna_m': unknown key"));
  }
}

}  // namespace
}  // namespace traverse::io
