// Many logs in one command: `traverse run A B C -o OUT` (a refused log never stops the others,
// summary.csv, exit 2, up-to-date logs skipped, --force, results independent of --jobs), the
// one-log-per-task `--batch` form and `traverse summarize` (issue 16, "Many logs").
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/jacobian_check.h"
#include "traverse/eval/metrics.h"

namespace traverse {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

struct Result {
  int code;
  std::string out, err;
};

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

class CliBatch : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("traverse_cli_batch_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    const fs::path straight = fs::path(testing::sourceDir()) / "datasets/logs/straight-1m";
    fs::copy(straight, dir_ / "A");
    fs::copy(straight, dir_ / "C");
    fs::create_directories(dir_ / "B");  // unreadable: a gyro.csv that is not a number
    std::ofstream(dir_ / "B" / "gyro.csv") << "t,wz\n0,abc\n";
  }
  void TearDown() override { fs::remove_all(dir_); }

  Result run(const std::string& args) {
    const std::string out = (dir_ / "stdout").string(), err = (dir_ / "stderr").string();
    const std::string cmd = std::string(TRAVERSE_CLI_PATH) + " " + args + " >" + out + " 2>" + err;
    const int status = std::system(cmd.c_str());
    return {WEXITSTATUS(status), slurp(out), slurp(err)};
  }
  std::string logs() const {
    return (dir_ / "A").string() + " " + (dir_ / "B").string() + " " + (dir_ / "C").string();
  }

  fs::path dir_;
};

TEST_F(CliBatch, ARefusedLogNeverStopsTheOthersAndUpToDateLogsAreSkipped) {
  const fs::path out = dir_ / "out";
  const Result r = run("run " + logs() + " -o " + out.string());
  EXPECT_EQ(r.code, 2) << r.err;
  // One line for the refused log, naming it and the reader's own error line.
  EXPECT_EQ(r.err, "traverse: B: refused: " + (dir_ / "B" / "rover.yaml").string() +
                       ": required file missing\n");
  for (const char* name : {"A", "C"}) {
    for (const char* f : {"dr.csv", "ekf.csv", "smoothed.csv", "segments.csv", "metrics.json"})
      EXPECT_TRUE(fs::exists(out / name / f)) << name << "/" << f;
    EXPECT_THAT(slurp(out / name / "status.json"), HasSubstr("\"status\": \"ok\""));
  }
  EXPECT_THAT(slurp(out / "B" / "status.json"), HasSubstr("\"status\": \"refused\""));
  const std::vector<std::string> rows = lines(slurp(out / "summary.csv"));
  ASSERT_EQ(rows.size(), 4u);  // header + three logs, in name order
  EXPECT_THAT(rows[0], StartsWith("log,status,message,seconds,duration_s,path_length_m,"));
  EXPECT_THAT(rows[1], StartsWith("A,ok,,"));
  EXPECT_THAT(rows[2], StartsWith("B,refused," + (dir_ / "B" / "rover.yaml").string()));
  EXPECT_THAT(rows[3], StartsWith("C,ok,,"));
  // The headline metrics are the ones metrics.json holds.
  const eval::MetricsReport a = eval::readMetricsJson(out / "A" / "metrics.json");
  ASSERT_EQ(a.estimators.size(), 4u);  // dr, ekf, rts, smoother
  EXPECT_EQ(a.estimators.at(3).estimator, "smoother");
  std::ostringstream ate;
  ate << *a.estimators.at(3).metrics.get("ate_posyaw_m");
  EXPECT_THAT(rows[1], HasSubstr(",32,"));  // the log's span, s
  EXPECT_THAT(rows[1], HasSubstr(ate.str().substr(0, 8)));

  // The same command again: A and C are up to date, B is tried (and refused) again.
  const auto written = fs::last_write_time(out / "A" / "smoothed.csv");
  const Result again = run("run " + logs() + " -o " + out.string());
  EXPECT_EQ(again.code, 2);
  EXPECT_THAT(again.out, HasSubstr("A: skipped, outputs up to date"));
  EXPECT_THAT(again.out, HasSubstr("C: skipped, outputs up to date"));
  EXPECT_EQ(fs::last_write_time(out / "A" / "smoothed.csv"), written);
  EXPECT_EQ(lines(slurp(out / "summary.csv")).size(), 4u);
  // Different options, an input newer than the outputs, or --force: run again.
  const Result other = run("run " + logs() + " -o " + out.string() + " --no-sun");
  EXPECT_THAT(other.out, Not(HasSubstr("skipped, outputs")));
  const Result same = run("run " + logs() + " -o " + out.string() + " --no-sun");
  EXPECT_THAT(same.out, HasSubstr("A: skipped"));
  fs::last_write_time(dir_ / "C" / "gyro.csv",
                      fs::last_write_time(out / "C" / "status.json") + std::chrono::seconds(5));
  const Result touched = run("run " + logs() + " -o " + out.string() + " --no-sun");
  EXPECT_THAT(touched.out, HasSubstr("A: skipped"));
  EXPECT_THAT(touched.out, HasSubstr("C: ok"));
  const Result forced = run("run --quiet --force " + logs() + " -o " + out.string() + " --no-sun");
  EXPECT_EQ(forced.code, 2);
  EXPECT_EQ(forced.out, "");  // --quiet: nothing but the refusal, on stderr
  EXPECT_THAT(forced.err, StartsWith("traverse: B: refused: "));
}

TEST_F(CliBatch, ResultsDoNotDependOnJobs) {
  const Result one = run("run --jobs 1 " + logs() + " -o " + (dir_ / "j1").string());
  const Result two = run("run --jobs 2 " + logs() + " -o " + (dir_ / "j2").string());
  EXPECT_EQ(one.code, 2);
  EXPECT_EQ(two.code, 2);
  for (const char* name : {"A", "C"}) {
    for (const char* f : {"dr.csv", "ekf.csv", "smoothed.csv", "metrics.json"})
      EXPECT_EQ(slurp(dir_ / "j1" / name / f), slurp(dir_ / "j2" / name / f)) << name << "/" << f;
  }
}

TEST_F(CliBatch, OneLogPerTaskThenSummarize) {
  // As a Slurm array or GNU parallel runs it (docs/cli.md): one log per task, same OUTDIR.
  const fs::path out = dir_ / "out";
  for (const char* name : {"A", "B", "C"})
    run("filter --batch " + (dir_ / name).string() + " -o " + out.string());
  fs::remove(out / "summary.csv");
  const Result s = run("summarize " + out.string());
  EXPECT_EQ(s.code, 0) << s.err;
  EXPECT_THAT(s.out, HasSubstr("(3 logs)"));
  const std::vector<std::string> rows = lines(slurp(out / "summary.csv"));
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_THAT(rows[1], StartsWith("A,ok,"));
  EXPECT_THAT(rows[2], StartsWith("B,refused,"));
  EXPECT_THAT(rows[3], StartsWith("C,ok,"));
  // A damaged metrics.json is named, with exit 2 and the old summary kept.
  const std::string before = slurp(out / "summary.csv");
  std::ofstream(out / "C" / "metrics.json") << "{\"log\": ";
  const Result bad = run("summarize " + out.string());
  EXPECT_EQ(bad.code, 2);
  EXPECT_THAT(bad.err, StartsWith((out / "C" / "metrics.json").string() + ": not JSON"));
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
  EXPECT_EQ(slurp(out / "summary.csv"), before);
  EXPECT_EQ(run("summarize " + (dir_ / "nothing").string()).code, 2);
}

TEST_F(CliBatch, TwoLogsOfOneNameAreRefusedBeforeAnythingRuns) {
  fs::create_directories(dir_ / "x");
  fs::copy(dir_ / "A", dir_ / "x" / "A");
  const Result r = run("run " + (dir_ / "A").string() + " " + (dir_ / "x" / "A").string() + " -o " +
                       (dir_ / "out").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_THAT(r.err, HasSubstr("has the same directory name as"));
  EXPECT_FALSE(fs::exists(dir_ / "out"));
}

// `bench accuracy --out DIR`: a JSON per scenario and the Markdown tables, all four estimators.
TEST_F(CliBatch, BenchAccuracyWritesJsonAndMarkdownPerScenario) {
  const fs::path out = dir_ / "bench";
  const Result r =
      run("bench accuracy --scenario straight-1m --runs 2 --jobs 2 --out " + out.string());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err, "");  // no progress bar when stderr is not a terminal
  const std::string json = slurp(out / "straight-1m.json");
  EXPECT_THAT(json, HasSubstr("\"runs\": 2"));
  const std::string md = slurp(out / "accuracy.md");
  EXPECT_THAT(md, StartsWith("### straight-1m — 2 runs, median (mean ± std)\n\n"
                             "| metric | dr | ekf | rts | smoother |\n|---|---|---|---|---|\n"));
  EXPECT_THAT(md, HasSubstr("| final_position_error_m | "));
  const Result bad = run("bench accuracy --runs 1 --json " + (dir_ / "x.json").string());
  EXPECT_EQ(bad.code, 2);
  EXPECT_THAT(bad.err, HasSubstr("one scenario only"));
}

}  // namespace
}  // namespace traverse
