// `traverse run` and `traverse evaluate` on a log whose only truth is position-only (gps.csv):
// the simulated straight-1m log with truth.csv replaced by its antenna track.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/jacobian_check.h"
#include "traverse/io/csv.h"

namespace traverse {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

struct Result {
  int code;
  std::string out, err;
};

std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

class CliGps : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("traverse_cli_gps_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    log_ = dir_ / "log";
    fs::copy(testing::sourceDir() + "/datasets/logs/straight-1m", log_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  Result run(const std::string& args) {
    const std::string out = (dir_ / "stdout").string(), err = (dir_ / "stderr").string();
    const int status = std::system(
        (std::string(TRAVERSE_CLI_PATH) + " " + args + " >" + out + " 2>" + err).c_str());
    return {WEXITSTATUS(status), slurp(out), slurp(err)};
  }

  /// Replaces truth.csv by gps.csv: the antenna at `lever` on the true body, 1 cm / 2 cm σ.
  void truthToGps(const Vec3d& lever) {
    const io::Stream truth = io::readCsv(log_ / "truth.csv", io::logStreamSpec("truth.csv"));
    io::Stream gps;
    gps.columns = {"x", "y", "z", "sx", "sy", "sz"};
    gps.t = truth.t;
    gps.values.resize(truth.size(), 6);
    for (Eigen::Index k = 0; k < truth.size(); ++k) {
      const Quatd q(truth.channel("qw")[k], truth.channel("qx")[k], truth.channel("qy")[k],
                    truth.channel("qz")[k]);
      const Vec3d p(truth.channel("x")[k], truth.channel("y")[k], truth.channel("z")[k]);
      gps.values.row(k) << (p + q.normalized() * lever).transpose(), 0.01, 0.01, 0.02;
    }
    io::writeCsv(log_ / "gps.csv", gps);
    fs::remove(log_ / "truth.csv");
    std::ofstream(log_ / "rover.yaml", std::ios::app)
        << "gps:\n  antenna_body_m: [" << lever.x() << ", " << lever.y() << ", " << lever.z()
        << "]\n";
  }

  fs::path dir_, log_;
};

TEST_F(CliGps, RunEvaluatesAgainstGpsWhenTruthIsAbsent) {
  truthToGps(Vec3d(0.1, 0.0, 0.5));
  const fs::path out = dir_ / "out";
  const Result r = run("run " + log_.string() + " -o " + out.string());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("ate_posyaw_m"));
  EXPECT_THAT(r.out, HasSubstr("metrics.json"));
  const std::string json = slurp(out / "metrics.json");
  for (const char* key : {"\"ate_posyaw_m\"", "\"ate_first_span_m\"", "\"gps_within_3sigma_pct\"",
                          "\"gps_fixes_used\"", "\"smoother\""})
    EXPECT_THAT(json, HasSubstr(key));
  EXPECT_THAT(json, Not(HasSubstr("roll_rmse_deg")));
  EXPECT_THAT(json, Not(HasSubstr("yaw_rmse_deg")));

  // `evaluate` on the same outputs writes the same metrics.json.
  fs::copy_file(out / "metrics.json", dir_ / "run_metrics.json");
  const Result e = run("evaluate " + out.string() + " --truth " + log_.string() + " --quiet");
  ASSERT_EQ(e.code, 0) << e.err;
  EXPECT_EQ(slurp(out / "metrics.json"), slurp(dir_ / "run_metrics.json"));
}

TEST_F(CliGps, EvaluateWithoutAnyTruthIsBadInput) {
  fs::remove(log_ / "truth.csv");
  const fs::path out = dir_ / "out";
  ASSERT_EQ(run("filter " + log_.string() + " -o " + out.string() + " --quiet").code, 0);
  const Result e = run("evaluate " + out.string() + " --truth " + log_.string());
  EXPECT_EQ(e.code, 2);
  EXPECT_THAT(e.err, HasSubstr((log_ / "truth.csv").string() + ": missing (and no gps.csv)"));
  EXPECT_EQ(std::count(e.err.begin(), e.err.end(), '\n'), 1) << e.err;
}

TEST_F(CliGps, BadGpsFileIsOneLineAndExitTwo) {
  truthToGps(Vec3d::Zero());
  std::ofstream(log_ / "gps.csv", std::ios::app) << "99,0,0,0,0.01,-1,0.01\n";
  const Result r = run("run " + log_.string() + " -o " + (dir_ / "out").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_THAT(r.err, HasSubstr((log_ / "gps.csv").string() + ":"));
  EXPECT_THAT(r.err, HasSubstr("column 'sy' out of physical range"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

// The simulator writes gps.csv on request (sensors.gps): the antenna track with its σ, the lever
// arm in rover.yaml, every other file byte-identical to the same seed without it; `run` on the
// log without truth.csv evaluates against it.
TEST_F(CliGps, SimulatedGpsTruth) {
  const fs::path sim = dir_ / "sim";
  const Result s = run("simulate straight-1m -o " + sim.string() +
                       " --seed 1 --quiet --set sensors.gps.rate_hz=5"
                       " --set 'sensors.gps.antenna_body_m=[0.1, 0, 0.5]'"
                       " --set 'sensors.gps.sigma_m=[0.01, 0.01, 0.02]'");
  ASSERT_EQ(s.code, 0) << s.err;
  for (const char* f : {"gyro.csv", "joints.csv", "sun.csv", "accel.csv", "cmd.csv", "truth.csv"})
    EXPECT_EQ(slurp(sim / f), slurp(log_ / f)) << f;
  const io::Stream gps = io::readCsv(sim / "gps.csv", io::logStreamSpec("gps.csv"));
  const io::Stream truth = io::readCsv(sim / "truth.csv", io::logStreamSpec("truth.csv"));
  EXPECT_NEAR(gps.t[gps.size() - 1] - gps.t[0], truth.t[truth.size() - 1] - truth.t[0], 0.2);
  EXPECT_EQ(gps.channel("sx")[0], 0.01);
  EXPECT_EQ(gps.channel("sz")[0], 0.02);
  // The antenna is 0.1 m ahead of and 0.5 m above the body origin (noise 1-2 cm).
  const Vec3d p0(truth.channel("x")[0], truth.channel("y")[0], truth.channel("z")[0]);
  const Quatd q0(truth.channel("qw")[0], truth.channel("qx")[0], truth.channel("qy")[0],
                 truth.channel("qz")[0]);
  const Vec3d a0(gps.channel("x")[0], gps.channel("y")[0], gps.channel("z")[0]);
  EXPECT_LT((a0 - (p0 + q0.normalized() * Vec3d(0.1, 0, 0.5))).norm(), 0.1);
  EXPECT_THAT(slurp(sim / "rover.yaml"), HasSubstr("antenna_body_m: [0.1, 0, 0.5]"));

  fs::remove(sim / "truth.csv");
  const Result r = run("run " + sim.string() + " -o " + (dir_ / "out").string() + " --quiet");
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string json = slurp(dir_ / "out" / "metrics.json");
  EXPECT_THAT(json, HasSubstr("\"gps_within_3sigma_pct\""));
  EXPECT_THAT(json, Not(HasSubstr("pitch_rmse_deg")));
}

}  // namespace
}  // namespace traverse
