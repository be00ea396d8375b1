// Whole log directories: reading (required and optional files, skip report), writing and
// reading back bit for bit, and the `traverse info` summary.
#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include "traverse/core/error.h"
#include "traverse/io/csv.h"
#include "traverse/io/log_reader.h"
#include "traverse/io/log_writer.h"

namespace traverse::io {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

fs::path rocky7Dir() {
  const char* env = std::getenv("TRAVERSE_SOURCE_DIR");
  return fs::path(env != nullptr ? env : TRAVERSE_SOURCE_DIR) / "datasets" / "rovers" / "rocky7";
}

const std::string kJointsHeader =
    "t,gamma0,gamma1,gamma2,lambda1,lambda2,psi1,psi2,psi3,psi4,psi5,psi6\n";

/// A stream of `rows` samples every `dt` seconds from t0, values random in [-1, 1].
Stream randomStream(std::vector<std::string> columns, int rows, double t0, double dt,
                    std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Stream s;
  s.columns = std::move(columns);
  s.t = Eigen::VectorXd::LinSpaced(rows, t0, t0 + dt * (rows - 1));
  s.values = Eigen::MatrixXd::NullaryExpr(rows, static_cast<Eigen::Index>(s.columns.size()),
                                          [&] { return u(rng); });
  return s;
}

bool sameBits(const Stream& a, const Stream& b) {
  return a.columns == b.columns && a.size() == b.size() && a.values.cols() == b.values.cols() &&
         std::memcmp(a.t.data(), b.t.data(), sizeof(double) * a.t.size()) == 0 &&
         std::memcmp(a.values.data(), b.values.data(), sizeof(double) * a.values.size()) == 0;
}

class IoLog : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("traverse_log_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  void write(const std::string& name, const std::string& text) {
    std::ofstream(dir_ / name, std::ios::binary) << text;
  }
  /// rover.yaml + rover.urdf of Rocky-7, a heading gyro and joints; nothing optional.
  void makeMinimalLog() {
    fs::copy_file(rocky7Dir() / "rover.yaml", dir_ / "rover.yaml");
    fs::copy_file(rocky7Dir() / "rover.urdf", dir_ / "rover.urdf");
    write("gyro.csv", "t,wz\n0,0.01\n0.1,0.02\n0.2,0.03\n");
    write("joints.csv", kJointsHeader + "0,0,0,0,0,0,0,0,0,0,0,0\n0.1,0,0,0,0,0,1,1,1,1,1,1\n");
  }
  void expectError(const std::string& file, long line, const std::string& words) {
    try {
      readLog(dir_);
      FAIL() << "no error";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), (dir_ / file).string());
      EXPECT_EQ(e.line(), line) << e.what();
      EXPECT_THAT(e.what(), HasSubstr(file));
      EXPECT_THAT(e.message(), HasSubstr(words)) << e.what();
    }
  }
  fs::path dir_;
};

TEST_F(IoLog, ReadsMinimalLog) {
  makeMinimalLog();
  const TraverseLog log = readLog(dir_);
  EXPECT_EQ(log.dir, dir_);
  EXPECT_EQ(log.config.name, "rocky7");
  EXPECT_GT(log.geometry.wheels[0].radius, 0.0);
  EXPECT_EQ(log.gyro.size(), 3);
  EXPECT_EQ(log.gyro.channel("wz")[2], 0.03);
  EXPECT_EQ(log.joints.values.cols(), 11);
  EXPECT_EQ(log.joints.channel("psi6")[1], 1.0);
  EXPECT_FALSE(log.sun || log.accel || log.cmd || log.truth);
}

TEST_F(IoLog, ReadsOptionalStreams) {
  makeMinimalLog();
  write("sun.csv", "t,s1,s2,valid\n0,0.1,0.2,1\n");
  write("truth.csv", "t,x,y,z,qw,qx,qy,qz,vx,vy,vz\n0,0,0,0,1,0,0,0,0.1,0,0\n");
  const TraverseLog log = readLog(dir_);
  ASSERT_TRUE(log.sun && log.truth);
  EXPECT_FALSE(log.accel || log.cmd);
  EXPECT_EQ(log.truth->channel("vx")[0], 0.1);
}

TEST_F(IoLog, MissingGyroNamesTheFile) {
  makeMinimalLog();
  fs::remove(dir_ / "gyro.csv");
  expectError("gyro.csv", 0, "required file missing");
}

TEST_F(IoLog, MissingJointsNamesTheFile) {
  makeMinimalLog();
  fs::remove(dir_ / "joints.csv");
  expectError("joints.csv", 0, "required file missing");
}

TEST_F(IoLog, MissingUrdfNamesTheFile) {
  makeMinimalLog();
  fs::remove(dir_ / "rover.urdf");
  expectError("rover.urdf", 0, "required file missing");
}

TEST_F(IoLog, MissingDirectory) {
  try {
    readLog(dir_ / "nope");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("nope: log directory not found"));
  }
}

TEST_F(IoLog, GyroAxesMustMatchRoverYaml) {
  makeMinimalLog();
  write("gyro.csv", "t,wx,wy,wz\n0,0,0,0.01\n");
  expectError("gyro.csv", 0, "rover.yaml gyro.axes is 'z'");
}

TEST_F(IoLog, StreamErrorsNameFileAndLine) {
  makeMinimalLog();
  write("accel.csv", "t,ax,ay,az\n0,0,0,9.8\n0.1,0,0,oops\n");
  expectError("accel.csv", 3, "non-numeric value 'oops' in column 'az'");
}

TEST_F(IoLog, SkipBadRowsReportsPerFile) {
  makeMinimalLog();
  write("gyro.csv", "t,wz\n0,0.01\n0.1,x\n-0.05,1\n0.2,0.03\n");
  write("joints.csv", kJointsHeader + "0,0,0,0,0,0,0,0,0,0,0,0\n0.1,0,0,0\n");
  ReadReport report;
  const TraverseLog log = readLog(dir_, ReadOptions{true, {}}, &report);
  EXPECT_EQ(log.gyro.size(), 2);
  EXPECT_EQ(log.joints.size(), 1);
  EXPECT_EQ(report.skipped_rows.at("gyro.csv"), 2);
  EXPECT_EQ(report.skipped_rows.at("joints.csv"), 1);
  EXPECT_EQ(report.totalSkipped(), 3);
  expectError("gyro.csv", 3, "non-numeric value 'x'");  // without the option it stops
}

TEST_F(IoLog, WriteThenReadIsBitForBit) {
  makeMinimalLog();
  std::mt19937_64 rng(7);
  TraverseLog log = readLog(dir_);
  log.gyro = randomStream({"wz"}, 500, 1e5, 0.01, rng);
  log.joints = randomStream(log.joints.columns, 250, 1e5, 0.02, rng);
  log.sun = randomStream({"s1", "s2", "valid"}, 20, 1e5 + 0.3, 0.25, rng);
  log.sun->values.col(2) = (log.sun->values.col(2).array() > 0.0).cast<double>();
  log.accel = randomStream({"ax", "ay", "az"}, 500, 1e5, 0.01, rng);
  log.cmd = randomStream({"vx", "vy", "vz", "wx", "wy", "wz"}, 7, 1e5, 0.7, rng);
  log.truth =
      randomStream({"x", "y", "z", "qw", "qx", "qy", "qz", "bx", "by", "bz"}, 90, 1e5, 0.05, rng);
  for (Eigen::Index k = 0; k < log.truth->size(); ++k)  // the reader wants unit quaternions
    log.truth->values.row(k).segment(3, 4).normalize();
  const fs::path out = dir_ / "copy";
  writeLog(out, log);
  EXPECT_TRUE(fs::exists(out / "rover.urdf"));
  EXPECT_TRUE(fs::exists(out / "rover.yaml"));
  const TraverseLog back = readLog(out);
  EXPECT_EQ(back.config.name, log.config.name);
  EXPECT_TRUE(sameBits(back.gyro, log.gyro));
  EXPECT_TRUE(sameBits(back.joints, log.joints));
  for (const auto& [a, b] : {std::pair{&back.sun, &log.sun},
                             {&back.accel, &log.accel},
                             {&back.cmd, &log.cmd},
                             {&back.truth, &log.truth}}) {
    ASSERT_TRUE(a->has_value());
    EXPECT_TRUE(sameBits(**a, **b));
  }
  // Rewritten in place without the optional streams: their old files must go.
  TraverseLog smaller = back;
  smaller.sun.reset();
  smaller.truth.reset();
  writeLog(out, smaller);
  const TraverseLog again = readLog(out);
  EXPECT_FALSE(again.sun || again.truth);
  EXPECT_TRUE(again.accel && again.cmd);
}

TEST_F(IoLog, WriteLogNeedsAUrdf) {
  makeMinimalLog();
  TraverseLog log = readLog(dir_);
  log.dir.clear();
  EXPECT_THROW(writeLog(dir_ / "elsewhere", log), std::invalid_argument);
  EXPECT_FALSE(fs::exists(dir_ / "elsewhere"));
}

TEST_F(IoLog, WriteStreamWithArbitraryColumns) {
  std::mt19937_64 rng(3);
  const Stream s = randomStream({"x_est", "y_est", "sigma_x"}, 10, 0.0, 0.1, rng);
  const fs::path file = dir_ / "trajectory.csv";
  writeStream(file, s);
  std::ifstream in(file);
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header, "t,x_est,y_est,sigma_x");
  EXPECT_TRUE(sameBits(readCsv(file, StreamSpec{}), s));
}

// --- summary ----------------------------------------------------------------------------------

TEST_F(IoLog, SummaryCountsRatesAndGaps) {
  Stream gyro;
  gyro.columns = {"wz"};
  // 10 Hz, with a 1 s hole after t = 0.4 and a 0.5 s one after t = 1.6.
  gyro.t.resize(12);
  gyro.t << 0.0, 0.1, 0.2, 0.3, 0.4, 1.4, 1.5, 1.6, 2.1, 2.2, 2.3, 2.4;
  gyro.values = Eigen::VectorXd::Zero(12);
  const StreamSummary s = summarizeStream("gyro", gyro);
  EXPECT_EQ(s.file, "gyro.csv");
  EXPECT_EQ(s.rows, 12);
  EXPECT_NEAR(s.median_rate_hz, 10.0, 1e-9);
  EXPECT_EQ(s.gaps, 2);
  EXPECT_NEAR(s.largest_gap_s, 1.0, 1e-12);
  EXPECT_EQ(s.t_first, 0.0);
  EXPECT_EQ(s.t_last, 2.4);
  EXPECT_FALSE(s.valid_rows.has_value());
}

TEST_F(IoLog, SummaryOfALog) {
  makeMinimalLog();
  write("sun.csv", "t,s1,s2,valid\n-1,0.1,0.2,1\n0,0.1,0.2,0\n1,0.1,0.2,1\n2,0.1,0.2,1\n");
  const LogSummary sum = summarize(readLog(dir_));
  ASSERT_EQ(sum.streams.size(), 3U);
  EXPECT_EQ(sum.streams[0].name, "gyro");
  EXPECT_EQ(sum.streams[1].name, "joints");
  EXPECT_EQ(sum.streams[2].name, "sun");
  EXPECT_EQ(sum.streams[2].valid_rows, 3);
  EXPECT_EQ(sum.streams[2].gaps, 0);
  EXPECT_EQ(sum.rover_name, "rocky7");
  EXPECT_EQ(sum.t_start, -1.0);
  EXPECT_EQ(sum.t_end, 2.0);
  EXPECT_EQ(sum.duration_s, 3.0);
  const std::string text = formatSummary(sum);
  EXPECT_THAT(text, HasSubstr("rocky7"));
  EXPECT_THAT(text, HasSubstr("duration  3.000 s"));
  EXPECT_THAT(text, HasSubstr("valid 3 of 4"));
  EXPECT_THAT(text, HasSubstr("heading only"));
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 8);
}

TEST_F(IoLog, BundledLogsRead) {
  for (const char* name : {"multi-stop", "straight-1m"}) {
    const fs::path dir = rocky7Dir().parent_path().parent_path() / "logs" / name;
    const TraverseLog log = readLog(dir);
    const LogSummary sum = summarize(log);
    EXPECT_EQ(sum.streams.size(), 6U) << name;  // gyro, joints, sun, accel, cmd, truth
    EXPECT_GT(sum.duration_s, 0.0);
    for (const StreamSummary& s : sum.streams) {
      EXPECT_GT(s.median_rate_hz, 0.0) << s.name;
      EXPECT_EQ(s.gaps, 0) << s.name;
    }
  }
}

}  // namespace
}  // namespace traverse::io
