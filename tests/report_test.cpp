// report.html (issue 16): the plot writer's pieces, the document's self-containment, and every
// bundled log's report rendered in headless Chromium — loads without a script or console error,
// draws its plots, and its screenshot is not blank. The Chromium tests are skipped, with a
// message, where Chromium is absent (scripts/setup.sh installs it, so CI runs them).
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/jacobian_check.h"
#include "traverse/report/svg_plot.h"

namespace traverse {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

size_t count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(ReportPlot, DecimationKeepsEveryBucketsExtremesAndTheEnds) {
  std::vector<double> x(10000), y(10000);
  for (size_t i = 0; i < x.size(); ++i) x[i] = 0.01 * i, y[i] = std::sin(0.001 * i);
  y[4321] = 50.0;   // a spike survives
  y[7000] = -50.0;  // and a dip
  y[8000] = NAN;    // and a break
  const auto idx = report::decimationIndices(x, y, 500);
  EXPECT_LE(idx.size(), 502u);
  EXPECT_TRUE(std::is_sorted(idx.begin(), idx.end()));
  auto has = [&](size_t i) { return std::find(idx.begin(), idx.end(), i) != idx.end(); };
  EXPECT_TRUE(has(0) && has(9999));
  EXPECT_TRUE(has(4321));
  EXPECT_TRUE(has(7000));
  EXPECT_TRUE(has(8000));
  // Short series are kept whole.
  EXPECT_EQ(report::decimationIndices({1, 2, 3}, {1, 2, 3}, 500).size(), 3u);
}

TEST(ReportPlot, SvgHoldsTheDataInDataUnitsAndEscapesText) {
  report::Plot p;
  p.title = "a < b & \"c\"";
  p.series.push_back({"line", "#000", {0, 1, 2}, {0, 1, NAN}, false, false, 1.5});
  p.bands.push_back({"band", "#00f", {0, 1, 2}, {-1, -1, -1}, {1, 1, 1}});
  p.spans.push_back({0.5, 1.0});
  const std::string svg = report::renderSvg(p);
  EXPECT_THAT(svg, HasSubstr("a &lt; b &amp; &quot;c&quot;"));
  EXPECT_THAT(svg, HasSubstr("d=\"M0 -0 1 -1\""));  // y negated; the NaN ends the line
  EXPECT_THAT(svg, HasSubstr("<svg class=\"data\""));
  EXPECT_THAT(svg, HasSubstr("class=\"span\""));
  report::Plot empty;
  empty.title = "nothing";
  EXPECT_THAT(report::renderSvg(empty), HasSubstr("no data"));
  EXPECT_EQ(report::htmlEscape("<&>\""), "&lt;&amp;&gt;&quot;");
}

class ReportOfLog : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("traverse_report_" + std::to_string(::getpid()) + "_" + GetParam());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  int sh(const std::string& cmd) {
    const int status = std::system(cmd.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  fs::path dir_;
};

/// Chromium's command, or "" when not installed.
std::string chromium() {
  for (const char* name : {"chromium", "chromium-browser", "google-chrome"}) {
    if (std::system((std::string("command -v ") + name + " >/dev/null 2>&1").c_str()) == 0)
      return name;
  }
  return "";
}

TEST_P(ReportOfLog, IsSelfContainedAndRendersInHeadlessChromium) {
  const fs::path log = fs::path(testing::sourceDir()) / "datasets/logs" / GetParam();
  const fs::path out = dir_ / "out";
  ASSERT_EQ(sh(std::string(TRAVERSE_CLI_PATH) + " run --quiet " + log.string() + " -o " +
               out.string() + " 2>" + (dir_ / "run.err").string()),
            0)
      << slurp(dir_ / "run.err");
  const std::string html = slurp(out / "report.html");
  ASSERT_FALSE(html.empty());
  EXPECT_LE(html.size(), 8u << 20);  // ≤ 8 MB
  EXPECT_GE(count(html, "<svg class=\"plot\""), 10u);
  // Nothing fetched: no source, no link, no stylesheet import, no URL but the SVG namespace
  // name the script passes to createElementNS (a name, never fetched).
  EXPECT_THAT(html, Not(HasSubstr(" src=")));
  EXPECT_THAT(html, Not(HasSubstr("<link")));
  EXPECT_THAT(html, Not(HasSubstr("url(")));
  EXPECT_THAT(html, Not(HasSubstr("@import")));
  EXPECT_EQ(count(html, "http"), count(html, "'http://www.w3.org/2000/svg'"));
  for (const char* section :
       {"id=\"metrics\"", "id=\"track\"", "id=\"elevation\"", "id=\"position\"", "id=\"attitude\"",
        "id=\"contact\"", "id=\"bias\"", "id=\"segments\"", "id=\"log\""})
    EXPECT_THAT(html, HasSubstr(section));

  const std::string browser = chromium();
  if (browser.empty()) GTEST_SKIP() << "Chromium not installed (scripts/setup.sh installs it)";
  const std::string flags =
      " --headless --no-sandbox --disable-gpu --no-first-run --disable-background-networking "
      "--hide-scrollbars --enable-logging=stderr --v=0 --user-data-dir=" +
      (dir_ / "profile").string();
  const std::string url = "file://" + fs::absolute(out / "report.html").string();
  // The DOM after the scripts ran: they count the plots drawn and the errors caught.
  ASSERT_EQ(sh("timeout 120 " + browser + flags + " --virtual-time-budget=5000 --dump-dom " + url +
               " >" + (dir_ / "dom.html").string() + " 2>" + (dir_ / "dom.err").string()),
            0)
      << slurp(dir_ / "dom.err");
  const std::string dom = slurp(dir_ / "dom.html");
  EXPECT_THAT(dom, HasSubstr("data-errors=\"0\""));
  // (No std::regex: GCC 12 warns inside <regex> under the asan preset's -Werror.)
  const size_t at = dom.find("data-plots=\"");
  ASSERT_NE(at, std::string::npos) << dom.substr(0, 300);
  const unsigned long plots = std::stoul(dom.substr(at + 12));
  EXPECT_EQ(plots, count(html, "<svg class=\"data\""));
  EXPECT_GE(plots, 6u);
  const std::string console = slurp(dir_ / "dom.err");
  EXPECT_THAT(console, Not(HasSubstr("Uncaught")));
  EXPECT_THAT(console, Not(HasSubstr("CONSOLE")));  // nothing logged to the console at all
  // The screenshot is not blank: far larger than a blank page's at the same size (a blank
  // 1100 x 3000 page is 16 kB; the reports measure 280-800 kB).
  std::ofstream(dir_ / "blank.html") << "<!DOCTYPE html><html><body></body></html>\n";
  for (const auto& [page, png] :
       {std::pair{url, "report.png"},
        std::pair{"file://" + (dir_ / "blank.html").string(), "blank.png"}}) {
    ASSERT_EQ(sh("timeout 120 " + browser + flags + " --window-size=1100,3000 --screenshot=" +
                 (dir_ / png).string() + " " + page + " >/dev/null 2>&1"),
              0);
  }
  const auto report_size = fs::file_size(dir_ / "report.png");
  const auto blank_size = fs::file_size(dir_ / "blank.png");
  EXPECT_GT(report_size, 8 * blank_size) << report_size << " vs blank " << blank_size;
}

INSTANTIATE_TEST_SUITE_P(BundledLogs, ReportOfLog,
                         ::testing::Values("straight-1m", "multi-stop", "wvu-pathfinder-s5t1",
                                           "wvu-pathfinder-test17run"),
                         [](const auto& info) {
                           std::string name = info.param;
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

}  // namespace
}  // namespace traverse
