// CSV stream files: bit-for-bit round trip, the contract's headers, and one precise error
// (file, line, words) per kind of bad input.
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include "support/rocky7.h"
#include "traverse/core/error.h"
#include "traverse/io/csv.h"

namespace traverse::io {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

class IoCsv : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("traverse_csv_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }
  /// Reads `text` as the contract's stream `name` (e.g. "gyro.csv").
  Stream read(const std::string& name, const std::string& text, const ReadOptions& options = {},
              ReadReport* report = nullptr) {
    return readCsv(write(name, text), logStreamSpec(name), options, report);
  }
  /// Expects reading `text` as `name` to fail at `line` with every one of `words` in the message.
  void expectError(const std::string& name, const std::string& text, long line,
                   const std::vector<std::string>& words, const ReadOptions& options = {}) {
    try {
      read(name, text, options);
      FAIL() << "no error for:\n" << text;
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), (dir_ / name).string());
      EXPECT_EQ(e.line(), line) << e.what();
      EXPECT_THAT(e.what(), HasSubstr(name));
      for (const std::string& w : words) EXPECT_THAT(e.message(), HasSubstr(w)) << e.what();
    }
  }
  fs::path dir_;
};

/// Doubles across the whole range: random mantissas with exponents from subnormal to huge.
double randomDouble(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> mantissa(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-1074, 1023);
  return std::ldexp(mantissa(rng), exponent(rng));
}

TEST_F(IoCsv, RoundTripIsBitForBit) {
  std::mt19937_64 rng(42);
  Stream s;
  s.columns = {"a", "b", "c"};
  const Eigen::Index n = 2000;
  s.t.resize(n);
  s.values.resize(n, 3);
  std::uniform_real_distribution<double> jitter(0.0, 0.005);
  for (Eigen::Index i = 0; i < n; ++i) {
    s.t[i] = 1e8 + static_cast<double>(i) * 0.01 + jitter(rng);  // mission time, µs resolution
    for (int c = 0; c < 3; ++c) s.values(i, c) = randomDouble(rng);
  }
  s.t[0] = -0.0;
  s.t[1] = std::numeric_limits<double>::denorm_min();
  const double specials[] = {-0.0,
                             0.0,
                             std::numeric_limits<double>::denorm_min(),
                             -std::numeric_limits<double>::min(),
                             std::numeric_limits<double>::max(),
                             -std::numeric_limits<double>::max(),
                             0.1,
                             1.0 / 3.0,
                             1e-300,
                             6.02214076e23};
  for (int i = 0; i < 10; ++i) s.values(i, 1) = specials[i];

  const fs::path file = dir_ / "out.csv";
  writeCsv(file, s);
  const Stream r = readCsv(file, StreamSpec{});
  ASSERT_EQ(r.columns, s.columns);
  ASSERT_EQ(r.size(), n);
  ASSERT_EQ(r.values.cols(), 3);
  EXPECT_EQ(std::memcmp(r.t.data(), s.t.data(), sizeof(double) * n), 0);
  EXPECT_EQ(std::memcmp(r.values.data(), s.values.data(), sizeof(double) * n * 3), 0);
  EXPECT_TRUE(std::signbit(r.values(0, 1)));
  EXPECT_FALSE(fs::exists(dir_ / "out.csv.tmp"));
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), formatCsv(s));
  EXPECT_EQ(text.str().substr(0, 8), "t,a,b,c\n");
}

TEST_F(IoCsv, CommentsEmptyLinesAndCrlfAreIgnored) {
  const Stream s =
      read("gyro.csv", "# exported 2024\n\nt,wz\n# a comment\n0,1.5\n\n  \n1,+2e-3\r\n2,-3");
  ASSERT_EQ(s.size(), 3);
  EXPECT_EQ(s.columns, std::vector<std::string>{"wz"});
  EXPECT_EQ(s.t[2], 2.0);
  EXPECT_EQ(s.values(0, 0), 1.5);
  EXPECT_EQ(s.values(1, 0), 2e-3);
  EXPECT_EQ(s.values(2, 0), -3.0);
}

TEST_F(IoCsv, HeadingOnlyAndThreeAxisGyro) {
  EXPECT_EQ(read("gyro.csv", "t,wz\n0,1\n").values.cols(), 1);
  const Stream s = read("gyro.csv", "t,wx,wy,wz\n0,1,2,3\n0.1,4,5,6\n");
  EXPECT_EQ(s.columns, (std::vector<std::string>{"wx", "wy", "wz"}));
  EXPECT_EQ(s.channel("wy")[1], 5.0);
  EXPECT_EQ(s.col("wz"), 2);
  EXPECT_EQ(s.col("wq"), -1);
  EXPECT_FALSE(s.has("t"));
  EXPECT_THROW(s.channel("wq"), std::out_of_range);
}

TEST_F(IoCsv, TruthWithAndWithoutOptionalGroups) {
  const std::string pose = "t,x,y,z,qw,qx,qy,qz";
  EXPECT_EQ(read("truth.csv", pose + "\n0,1,2,3,1,0,0,0\n").values.cols(), 7);
  const Stream all = read("truth.csv", pose +
                                           ",xi1,xi2,xi3,xi4,xi5,xi6,bx,by,bz,vx,vy,vz,wx,wy,wz\n"
                                           "0,1,2,3,1,0,0,0,1,2,3,4,5,6,7,8,9,10,11,12,13,14,15\n");
  EXPECT_EQ(all.values.cols(), 22);
  EXPECT_EQ(all.channel("wz")[0], 15.0);
  const Stream some = read("truth.csv", pose + ",bx,by,bz,wx,wy,wz\n0,1,2,3,1,0,0,0,1,2,3,4,5,6\n");
  EXPECT_EQ(some.channel("bz")[0], 3.0);
  EXPECT_FALSE(some.has("vx"));
  expectError("truth.csv", pose + ",vx,vy,vz,bx,by,bz\n0,1,2,3,1,0,0,0,1,2,3,4,5,6\n", 1,
              {"wrong order", "expected order '" + pose + ",bx,by,bz,vx,vy,vz'"});
  expectError("truth.csv", pose + ",bx,by\n0,1,2,3,1,0,0,0,1,2\n", 1, {"missing column 'bz'"});
}

// --- one test per error ----------------------------------------------------------------------

TEST_F(IoCsv, MissingFile) {
  try {
    readCsv(dir_ / "sun.csv", logStreamSpec("sun.csv"));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), (dir_ / "sun.csv").string());
    EXPECT_EQ(e.line(), 0);
    EXPECT_THAT(e.what(), HasSubstr("sun.csv: file not found"));
  }
}

TEST_F(IoCsv, EmptyFile) {
  expectError("gyro.csv", "", 1, {"empty file", "no header", "'t,wz' or 't,wx,wy,wz'"});
  expectError("gyro.csv", "# only a comment\n\n", 3, {"empty file"});
}

TEST_F(IoCsv, HeaderOnly) {
  expectError("accel.csv", "# c\nt,ax,ay,az\n\n", 2, {"header only", "no data rows"});
}

TEST_F(IoCsv, MissingColumn) {
  // joints.csv's columns are the rover's: Rocky-7's here.
  const std::string text =
      "t,gamma0,gamma1,lambda1,lambda2,psi1,psi2,psi3,psi4,psi5,psi6\n0,0,0,0,0,0,0,0,0,0,0\n";
  try {
    readCsv(write("joints.csv", text), logStreamSpec("joints.csv", testing::rocky7()));
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 1);
    EXPECT_THAT(e.message(), HasSubstr("missing column 'gamma2'"));
  }
  expectError("gyro.csv", "wz\n1\n", 1, {"missing column 't'"});
}

TEST_F(IoCsv, ColumnsInWrongOrder) {
  expectError("sun.csv", "t,s2,s1,valid\n0,0.1,0.2,1\n", 1,
              {"wrong order", "expected order 't,s1,s2,valid'"});
}

// A control byte in a column name (a lone CR: found by fuzz_csv, the writer then refused the
// stream the reader had accepted) is bad input, quoted printably.
TEST_F(IoCsv, ControlCharacterInColumnName) {
  expectError("joints.csv", "t,a\rb,c\n0,1,2\n", 1, {"control character in column name 'a\\x0Db'"});
  expectError("joints.csv", "t,a\tb\n0,1\n", 1, {"control character in column name 'a\\x09b'"});
}

TEST_F(IoCsv, UnknownExtraColumn) {
  expectError("accel.csv", "t,ax,ay,az,temp\n0,0,0,9.8,20\n", 1, {"unknown column 'temp'"});
  expectError("cmd.csv", "t,vx,vy,vz,wx,wy,wz,wz\n", 1, {"duplicate column 'wz'"});
}

TEST_F(IoCsv, NonNumericField) {
  expectError("gyro.csv", "t,wx,wy,wz\n0,1,2,3\n# c\n1,2,abc,4\n", 4,
              {"non-numeric value 'abc'", "column 'wy'"});
  expectError("gyro.csv", "t,wz\n0,1\n1, 2\n", 3, {"non-numeric value ' 2'", "column 'wz'"});
  expectError("gyro.csv", "t,wz\n0,1\n1,\n2,3\n", 3, {"empty value in column 'wz'"});
  expectError("gyro.csv", "t,wz\n0,1e999\n", 2, {"'1e999'", "beyond the range of a double"});
}

TEST_F(IoCsv, NanOrInf) {
  expectError("gyro.csv", "t,wz\n0,1\n1,nan\n", 3, {"NaN in column 'wz'"});
  expectError("gyro.csv", "t,wz\n0,1\ninf,1\n", 3, {"infinite value inf in column 't'"});
  expectError("gyro.csv", "t,wz\n0,-Infinity\n", 2, {"infinite value -inf in column 'wz'"});
}

TEST_F(IoCsv, WrongFieldCount) {
  expectError("accel.csv", "t,ax,ay,az\n0,1,2,3\n1,1,2,3,4\n", 3,
              {"wrong number of fields", "expected 4 fields, found 5"});
  expectError("accel.csv", "t,ax,ay,az\n0,1,2\n1,1,2,3\n", 2, {"expected 4 fields, found 3"});
}

TEST_F(IoCsv, TruncatedLastLine) {
  expectError("accel.csv", "t,ax,ay,az\n0,1,2,3\n1,1,2", 3,
              {"truncated last line", "expected 4 fields, found 3"});
  expectError("accel.csv", "t,ax,ay,az\n0,1,2,3\n1,1,2,", 3,
              {"truncated last line", "empty value in column 'az'"});
}

TEST_F(IoCsv, NonIncreasingTime) {
  expectError("gyro.csv", "t,wz\n0,1\n1.5,1\n1.25,1\n", 4,
              {"non-increasing time", "t=1.25", "t=1.5"});
}

TEST_F(IoCsv, DuplicateTime) {
  expectError("gyro.csv", "t,wz\n0,1\n1.5,1\n1.5,2\n", 4,
              {"duplicate time", "t=1.5 equals", "t=1.5"});
}

TEST_F(IoCsv, ValueOutOfPhysicalRange) {
  expectError("sun.csv", "t,s1,s2,valid\n0,0.5,0.5,1\n1,1.5,0.5,1\n", 3,
              {"value 1.5 in column 's1'", "out of physical range [-1, 1]"});
  expectError("sun.csv", "t,s1,s2,valid\n0,0.5,-1.01,1\n", 2, {"column 's2'", "-1.01"});
  expectError("sun.csv", "t,s1,s2,valid\n0,0.5,0.5,0.5\n", 2,
              {"value 0.5 in column 'valid' must be 0 or 1"});
}

// --- skipping ---------------------------------------------------------------------------------

TEST_F(IoCsv, SkipBadRowsCountsEachDroppedRow) {
  const std::string text =
      "t,s1,s2,valid\n"
      "0,0.1,0.2,1\n"
      "1,abc,0.2,1\n"     // non-numeric
      "2,nan,0.2,1\n"     // NaN
      "3,0.1,0.2\n"       // field count
      "-0.5,0.1,0.2,1\n"  // non-increasing
      "0,0.1,0.2,1\n"     // duplicate of the last kept row
      "4,2.0,0.2,1\n"     // out of range
      "5,0.1,0.2,2\n"     // valid not boolean
      "6,0.3,0.4,0\n"
      "7,0.1";  // truncated
  ReadReport report;
  const Stream s = read("sun.csv", text, ReadOptions{true, {}}, &report);
  ASSERT_EQ(s.size(), 2);
  EXPECT_EQ(s.t[1], 6.0);
  EXPECT_EQ(s.values(1, 1), 0.4);
  EXPECT_EQ(report.skipped_rows.at("sun.csv"), 8);
  EXPECT_EQ(report.totalSkipped(), 8);
  read("sun.csv", text, ReadOptions{true, {}}, &report);  // counts accumulate per file
  EXPECT_EQ(report.totalSkipped(), 16);
}

TEST_F(IoCsv, SkipBadRowsStillStopsOnHeaderProblems) {
  const ReadOptions skip{true, {}};
  expectError("gyro.csv", "t,wq\n0,1\n", 1, {"unknown column 'wq'"}, skip);
  expectError("gyro.csv", "t,wz\n", 1, {"header only"}, skip);
  expectError("gyro.csv", "t,wz\n0,x\n1,y\n", 1, {"no usable data rows", "all 2 skipped"}, skip);
}

TEST_F(IoCsv, CleanReadReportsNothing) {
  ReadReport report;
  read("gyro.csv", "t,wz\n0,1\n", ReadOptions{true, {}}, &report);
  EXPECT_TRUE(report.skipped_rows.empty());
  EXPECT_EQ(report.totalSkipped(), 0);
}

// --- writing ----------------------------------------------------------------------------------

TEST_F(IoCsv, WriterRefusesWhatTheReaderWouldReject) {
  Stream s;
  s.columns = {"wz"};
  s.t = Eigen::Vector2d(0.0, 1.0);
  s.values = Eigen::Vector2d(1.0, std::nan(""));
  EXPECT_THROW(formatCsv(s), std::invalid_argument);
  s.values(1, 0) = 2.0;
  s.t[1] = 0.0;
  EXPECT_THROW(formatCsv(s), std::invalid_argument);
  s.t[1] = 1.0;
  s.columns = {"w,z"};
  EXPECT_THROW(formatCsv(s), std::invalid_argument);
  s.columns = {"wz", "wy"};
  EXPECT_THROW(formatCsv(s), std::invalid_argument);
}

TEST_F(IoCsv, FailedWriteKeepsThePreviousFile) {
  Stream s;
  s.columns = {"wz"};
  s.t = Eigen::Vector2d(0.0, 1.0);
  s.values = Eigen::Vector2d(1.0, 2.0);
  const fs::path file = dir_ / "gyro.csv";
  writeCsv(file, s);
  Stream bad = s;
  bad.values(1, 0) = std::numeric_limits<double>::infinity();
  EXPECT_THROW(writeCsv(file, bad), std::invalid_argument);
  EXPECT_EQ(readCsv(file, logStreamSpec("gyro.csv")).values(1, 0), 2.0);
  EXPECT_FALSE(fs::exists(dir_ / "gyro.csv.tmp"));
  EXPECT_THROW(writeCsv(dir_ / "no_such_dir" / "gyro.csv", s), std::runtime_error);
}

}  // namespace
}  // namespace traverse::io
