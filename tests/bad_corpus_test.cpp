// The bad-file corpus (tests/data/bad/, written by scripts/make_bad_corpus.py): `traverse run` on
// every case directory gives the exit code and the first stderr line its expected.txt names —
// one line `FILE:LINE: problem` and exit 2 for bad input; exit 0, and a `warning:` line where
// the data is dirty but usable; the clean case's numbers for a BOM, CRLF line ends and comments.
#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "support/jacobian_check.h"

namespace traverse {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

struct Expected {
  int exit_code = -1;
  std::string stderr_first_line;  ///< substring; empty = not checked
  int lines = -1;                 ///< stderr line count; −1 = not checked
  bool same_outputs = false;
  std::vector<std::string> env;  ///< NAME=VALUE
  std::string grow_file;
  std::uintmax_t grow_bytes = 0;
};

Expected readExpected(const fs::path& file) {
  Expected e;
  std::istringstream in(slurp(file));
  std::string line;
  while (std::getline(in, line)) {
    const auto space = line.find(' ');
    const std::string key = line.substr(0, space);
    const std::string value = space == std::string::npos ? "" : line.substr(space + 1);
    if (key == "exit") {
      e.exit_code = std::stoi(value);
    } else if (key == "stderr") {
      e.stderr_first_line = value;
    } else if (key == "lines") {
      e.lines = std::stoi(value);
    } else if (key == "same-outputs") {
      e.same_outputs = true;
    } else if (key == "env") {
      e.env.push_back(value);
    } else if (key == "grow") {
      std::istringstream g(value);
      g >> e.grow_file >> e.grow_bytes;
    } else if (!key.empty()) {
      ADD_FAILURE() << file << ": unknown key '" << key << "'";
    }
  }
  if (e.exit_code == 2 && e.lines < 0) e.lines = 1;
  return e;
}

struct RunResult {
  int code;
  std::string err;
};

RunResult traverseRun(const fs::path& log, const fs::path& out,
                      const std::vector<std::string>& env) {
  std::string cmd = "env";
  for (const std::string& kv : env) cmd += " '" + kv + "'";
  const fs::path err = out.string() + ".err";
  cmd += " " + std::string(TRAVERSE_CLI_PATH) + " run --quiet '" + log.string() + "' -o '" +
         out.string() + "' 2>'" + err.string() + "'";
  const int status = std::system(cmd.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(err)};
}

/// The estimator outputs that must not depend on how the log's text was laid out
/// (segments.csv and metrics.json hold solve times and the log's name).
const char* const kCompared[] = {"dr.csv",  "dr.tum",       "ekf.csv",
                                 "ekf.tum", "smoothed.csv", "smoothed.tum"};

TEST(BadFileCorpus, EveryCaseGivesItsExpectedExitCodeAndMessage) {
  const fs::path corpus = fs::path(testing::sourceDir()) / "tests" / "data" / "bad";
  const fs::path work = fs::temp_directory_path() / "traverse_bad_corpus";
  fs::remove_all(work);
  fs::create_directories(work);
  std::vector<fs::path> cases;
  for (const auto& entry : fs::directory_iterator(corpus))
    if (entry.is_directory()) cases.push_back(entry.path());
  std::sort(cases.begin(), cases.end());
  ASSERT_GE(cases.size(), 25U);

  const fs::path clean_out = work / "clean.out";
  ASSERT_EQ(traverseRun(corpus / "clean", clean_out, {}).code, 0);
  int bad = 0;
  for (const fs::path& dir : cases) {
    SCOPED_TRACE(dir.filename().string());
    const Expected e = readExpected(dir / "expected.txt");
    ASSERT_GE(e.exit_code, 0) << "expected.txt has no 'exit' line";
    // A private copy: the run must not depend on or touch the corpus, and `grow` makes a
    // sparse file there (a 2.5 GB file in the repository would not do).
    const fs::path log = work / dir.filename();
    fs::copy(dir, log, fs::copy_options::recursive);
    fs::remove(log / "expected.txt");
    if (!e.grow_file.empty()) fs::resize_file(log / e.grow_file, e.grow_bytes);
    const fs::path out = work / (dir.filename().string() + ".out");
    const RunResult r = traverseRun(log, out, e.env);
    fs::remove_all(log);  // the sparse file goes at once
    EXPECT_EQ(r.code, e.exit_code) << r.err;
    const std::string first = r.err.substr(0, r.err.find('\n'));
    if (!e.stderr_first_line.empty()) {
      EXPECT_NE(first.find(e.stderr_first_line), std::string::npos)
          << "first stderr line: " << first;
    }
    if (e.lines >= 0) {
      EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), e.lines) << r.err;
    }
    if (e.exit_code == 2) {
      ++bad;
      // One line naming the file (FILE:LINE: problem, or FILE: problem for a whole file).
      EXPECT_NE(first.find(log.string() + "/"), std::string::npos) << first;
    }
    if (e.same_outputs) {
      for (const char* f : kCompared) EXPECT_EQ(slurp(out / f), slurp(clean_out / f)) << f;
    }
  }
  EXPECT_GE(bad, 25);
  fs::remove_all(work);
}

}  // namespace
}  // namespace traverse
