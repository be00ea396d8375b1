// The `traverse` command end to end: exit codes and the one-line error contract.
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/jacobian_check.h"
#include "traverse/eval/metrics.h"

namespace traverse {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

struct Result {
  int code;
  std::string out, err;
};

Result run(const std::string& args) {
  // Unique files per call: ctest runs tests in parallel processes.
  static int calls = 0;
  const std::string tag =
      std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
      std::to_string(++calls);
  const auto dir = std::filesystem::temp_directory_path();
  const std::string out = (dir / ("traverse_cli_" + tag + ".out")).string();
  const std::string err = (dir / ("traverse_cli_" + tag + ".err")).string();
  const std::string cmd = std::string(TRAVERSE_CLI_PATH) + " " + args + " >" + out + " 2>" + err;
  const int status = std::system(cmd.c_str());
  auto slurp = [](const std::string& p) {
    std::ifstream f(p);
    return std::string(std::istreambuf_iterator<char>(f), {});
  };
  Result r{WEXITSTATUS(status), slurp(out), slurp(err)};
  std::filesystem::remove(out);
  std::filesystem::remove(err);
  return r;
}

std::string bundled(const std::string& name) {
  return testing::sourceDir() + "/datasets/logs/" + name;
}

TEST(Cli, InfoOnBundledLogSucceeds) {
  const Result r = run("info " + bundled("multi-stop"));
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("joints"));
  EXPECT_THAT(r.out, HasSubstr("rocky7"));
  EXPECT_EQ(r.err, "");
}

TEST(Cli, BadLogGivesOneLineAndExitTwo) {
  const auto dir = std::filesystem::temp_directory_path() / "traverse_cli_bad";
  std::filesystem::remove_all(dir);
  std::filesystem::copy(bundled("straight-1m"), dir);
  {
    std::ofstream f(dir / "sun.csv");
    f << "t,s1,s2,valid\n0,0.1,0.2,1\n0.5,1.7,0.2,1\n";
  }
  const Result r = run("info " + dir.string());
  EXPECT_EQ(r.code, 2);
  EXPECT_THAT(r.err, StartsWith((dir / "sun.csv").string() + ":3: "));
  EXPECT_THAT(r.err, HasSubstr("s1"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  const Result skipped = run("info --skip-bad-rows " + dir.string());
  EXPECT_EQ(skipped.code, 0);
  EXPECT_THAT(skipped.err, HasSubstr("sun.csv: skipped 1 bad row"));
  std::filesystem::remove_all(dir);
}

TEST(Cli, UsageErrorsExitTwo) {
  EXPECT_EQ(run("").code, 2);
  EXPECT_EQ(run("info").code, 2);
  EXPECT_EQ(run("no-such-command").code, 2);
  EXPECT_EQ(run("simulate no-such-scenario -o /tmp/x").code, 2);
  EXPECT_EQ(run("info /no/such/dir").code, 2);
}

TEST(Cli, HelpAndVersionExitZero) {
  for (const char* args : {"--help", "info --help", "simulate --help", "--version"}) {
    const Result r = run(args);
    EXPECT_EQ(r.code, 0) << args;
    EXPECT_FALSE(r.out.empty()) << args;
  }
}

TEST(Cli, SimulateWritesALogThatReadsBack) {
  const auto dir = std::filesystem::temp_directory_path() / "traverse_cli_sim";
  std::filesystem::remove_all(dir);
  const Result r =
      run("simulate obstacle -o " + dir.string() + " --seed 3 --set path.1.straight=0.2 --quiet");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(run("info " + dir.string()).code, 0);
  std::filesystem::remove_all(dir);
}

// A creep in the first rest window (the wheels roll 0.3 mm/s until the drive starts at 5 s,
// under every detector threshold): `run` still succeeds, and says on stderr that the apparent
// rest is not one and was treated as motion.
TEST(Cli, RunWarnsOfARestThatIsNotOne) {
  const auto dir = std::filesystem::temp_directory_path() / "traverse_cli_creep";
  std::filesystem::remove_all(dir);
  std::filesystem::copy(bundled("straight-1m"), dir);
  std::ifstream in(dir / "joints.csv");
  std::string header, line, text;
  std::getline(in, header);
  text = header + "\n";
  while (std::getline(in, line)) {
    std::vector<double> v;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) v.push_back(std::stod(cell));
    const double creep = 3e-4 * std::min(v[0] - 5.0, 0.0) / 0.065;  // wheel radius 0.065 m
    for (size_t c = 6; c < 12; ++c) v[c] += creep;                  // psi1..psi6
    std::ostringstream row;
    row.precision(17);
    for (size_t c = 0; c < v.size(); ++c) row << (c ? "," : "") << v[c];
    text += row.str() + "\n";
  }
  in.close();
  std::ofstream(dir / "joints.csv") << text;
  const Result r = run("run " + dir.string() + " -o " + (dir / "out").string());
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("warning: "));
  EXPECT_THAT(r.err, HasSubstr("is not at rest"));
  EXPECT_THAT(r.err, HasSubstr("treated as motion"));
  std::filesystem::remove_all(dir);
}

// straight-1m with 15 s of gyro.csv missing while it drives: exit 0, a warning naming stream,
// time and kind, and the smoother segment that spans the gap is marked on stdout.
TEST(Cli, RunWarnsOfAGyroGapAndMarksTheSegment) {
  const auto dir = std::filesystem::temp_directory_path() / "traverse_cli_gyro_gap";
  std::filesystem::remove_all(dir);
  std::filesystem::copy(bundled("straight-1m"), dir);
  std::ifstream in(dir / "gyro.csv");
  std::string line, text;
  std::getline(in, line);
  text = line + "\n";
  while (std::getline(in, line)) {
    const double t = std::stod(line.substr(0, line.find(',')));
    if (!(t > 5.0 && t < 20.0)) text += line + "\n";
  }
  in.close();
  std::ofstream(dir / "gyro.csv") << text;
  const Result r = run("run " + dir.string() + " -o " + (dir / "out").string());
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("warning: gyro.csv: gap of 15.0 s at t=5.0"));
  EXPECT_THAT(r.out, HasSubstr("spans a gyro.csv gap of 15.0 s at t=5.0"));
  std::filesystem::remove_all(dir);
}

// A skid-steer rover: the EKF's estimate of the ICRs' half-track error is printed and every
// segments.csv row carries it with its σ.
TEST(Cli, FilterReportsTheSkidSteerIcrsEstimate) {
  const auto dir = std::filesystem::temp_directory_path() / "traverse_cli_icr";
  std::filesystem::remove_all(dir);
  const Result r = run("filter " + bundled("wvu-pathfinder-test17run") + " -o " + dir.string());
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("ekf: skid-steer ICRs' half-track error at the end "));
  EXPECT_THAT(r.out, HasSubstr("(prior sigma 0.1): ICRs at y = "));
  std::ifstream in(dir / "segments.csv");
  std::string header, row;
  std::getline(in, header);
  EXPECT_THAT(header, ::testing::EndsWith(",icr_half_track_error_m,sigma_icr_half_track_error_m"));
  int rows = 0;
  while (std::getline(in, row)) {
    ++rows;
    const double sigma = std::stod(row.substr(row.rfind(',') + 1));
    EXPECT_GT(sigma, 0.0) << row;
    EXPECT_LT(sigma, 0.1) << row;
  }
  EXPECT_GE(rows, 3);
  std::filesystem::remove_all(dir);
}

// A rover.yaml that declares a gyro three times quieter than its readings at rest: the measured
// noise is used with a `noise` warning, counted in metrics.json; --no-noise-check keeps the
// declared one and says nothing.
TEST(Cli, RunUsesTheNoiseMeasuredAtRestUnlessTold) {
  const auto dir = std::filesystem::temp_directory_path() / "traverse_cli_noise_check";
  std::filesystem::remove_all(dir);
  std::filesystem::copy(bundled("straight-1m"), dir);
  std::ifstream in(dir / "rover.yaml");
  std::string line, text;
  while (std::getline(in, line))
    text += (line.rfind("  noise_rad_s:", 0) == 0 ? "  noise_rad_s: 0.0003" : line) + "\n";
  in.close();
  std::ofstream(dir / "rover.yaml") << text;
  const Result r = run("filter " + dir.string() + " -o " + (dir / "out").string());
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("warning: gyro.csv: noise at rest"));
  EXPECT_THAT(r.err,
              HasSubstr("gyro.noise_rad_s 0.0003 in rover.yaml: the measured value is used"));
  const eval::MetricsReport m = eval::readMetricsJson(dir / "out" / "metrics.json");
  ASSERT_TRUE(m.diagnostics);
  EXPECT_EQ(m.diagnostics->countsByKind().at("noise"), 1);
  const Result kept =
      run("filter --no-noise-check " + dir.string() + " -o " + (dir / "kept").string());
  EXPECT_EQ(kept.code, 0) << kept.err;
  EXPECT_THAT(kept.err, Not(HasSubstr("noise at rest")));
  std::filesystem::remove_all(dir);
}

// A joints clock 0.2 s late: found, said on stderr, counted in metrics.json, and removed;
// --no-clock-align keeps the stamps and says nothing.
TEST(Cli, RunFindsAndRemovesAJointsClockOffset) {
  const auto dir = std::filesystem::temp_directory_path() / "traverse_cli_clock";
  std::filesystem::remove_all(dir);
  ASSERT_EQ(
      run("simulate straight-1m --set faults.clock_offset.joints=0.2 -o " + dir.string()).code, 0);
  const Result r = run("filter " + dir.string() + " -o " + (dir / "out").string());
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("warning: joints.csv: clock offset of +0.2"));
  EXPECT_THAT(r.err, HasSubstr("its stamps moved by -0.2"));
  const eval::MetricsReport m = eval::readMetricsJson(dir / "out" / "metrics.json");
  ASSERT_TRUE(m.diagnostics);
  EXPECT_EQ(m.diagnostics->countsByKind().at("clock_offset"), 1);
  const Result kept =
      run("filter --no-clock-align " + dir.string() + " -o " + (dir / "kept").string());
  EXPECT_EQ(kept.code, 0) << kept.err;
  EXPECT_THAT(kept.err, Not(HasSubstr("clock offset")));
  std::filesystem::remove_all(dir);
}

// A sun clock 0.3 s late on a turn in place: sun.csv is the stream named and moved (not the
// joints), its offset counted in metrics.json with the file's own name.
TEST(Cli, RunFindsAndRemovesASunClockOffset) {
  const auto dir = std::filesystem::temp_directory_path() / "traverse_cli_sun_clock";
  std::filesystem::remove_all(dir);
  ASSERT_EQ(
      run("simulate turn-in-place-360 --set faults.clock_offset.sun=0.3 -o " + dir.string()).code,
      0);
  const Result r = run("filter " + dir.string() + " -o " + (dir / "out").string());
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("warning: sun.csv: clock offset of +0.2"));
  EXPECT_THAT(r.err, HasSubstr("against the gyro"));
  EXPECT_THAT(r.err, Not(HasSubstr("joints.csv: clock offset")));
  const eval::MetricsReport m = eval::readMetricsJson(dir / "out" / "metrics.json");
  ASSERT_TRUE(m.diagnostics);
  EXPECT_EQ(m.diagnostics->countsByKind().at("clock_offset"), 1);
  std::filesystem::remove_all(dir);
}

// A log without truth still gets metrics.json: the diagnostics, nothing to evaluate. A gap the
// run warns of is the one the file lists.
TEST(Cli, FilterWithoutTruthWritesTheDiagnostics) {
  const auto dir = std::filesystem::temp_directory_path() / "traverse_cli_no_truth";
  std::filesystem::remove_all(dir);
  std::filesystem::copy(bundled("straight-1m"), dir);
  std::filesystem::remove(dir / "truth.csv");
  std::ifstream in(dir / "gyro.csv");
  std::string line, text;
  while (std::getline(in, line)) {
    const double t = line[0] == 't' ? -1.0 : std::stod(line.substr(0, line.find(',')));
    if (!(t > 10.0 && t < 25.0)) text += line + "\n";
  }
  in.close();
  std::ofstream(dir / "gyro.csv") << text;
  const Result r = run("filter --quiet " + dir.string() + " -o " + (dir / "out").string());
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err, "warning: gyro.csv: gap of 15.0 s at t=10.0\n");
  const eval::MetricsReport m = eval::readMetricsJson(dir / "out" / "metrics.json");
  EXPECT_EQ(m.log, "traverse_cli_no_truth");
  EXPECT_FALSE(m.evaluated);
  ASSERT_TRUE(m.diagnostics);
  EXPECT_EQ(m.diagnostics->countsByKind().at("gap"), 1);
  ASSERT_EQ(m.diagnostics->findings.size(), 1u);
  EXPECT_EQ(m.diagnostics->findings[0].kind, "gap");
  EXPECT_EQ(m.diagnostics->findings[0].t, 10.0);
  EXPECT_EQ(m.diagnostics->findings[0].duration_s, 15.0);
  ASSERT_TRUE(m.run);  // the run block is there with or without truth
  EXPECT_GT(m.run->estimated_path_length_m, 0.5);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace traverse
