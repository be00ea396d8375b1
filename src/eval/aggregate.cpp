#include "traverse/eval/aggregate.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "eval/table.h"
#include "traverse/io/atomic_file.h"

#include <nlohmann/json.hpp>

namespace traverse::eval {

Statistics summarize(std::vector<double> values) {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  Statistics s;
  s.count = values.size();
  const bool any_nan =
      std::any_of(values.begin(), values.end(), [](double v) { return std::isnan(v); });
  if (values.empty() || any_nan) {
    s.mean = s.stddev = s.median = s.max = kNaN;
    return s;
  }
  const double n = static_cast<double>(values.size());
  s.mean = std::accumulate(values.begin(), values.end(), 0.0) / n;
  if (values.size() > 1) {
    double sum_sq = 0.0;
    for (double v : values) sum_sq += (v - s.mean) * (v - s.mean);
    s.stddev = std::sqrt(sum_sq / (n - 1.0));
  } else {
    s.stddev = kNaN;  // the sample standard deviation of one value is undefined
  }
  std::sort(values.begin(), values.end());
  const std::size_t mid = values.size() / 2;
  s.median = values.size() % 2 == 1 ? values[mid] : 0.5 * (values[mid - 1] + values[mid]);
  s.max = values.back();
  return s;
}

AccuracyReport aggregate(std::string scenario, long runs, const std::vector<EstimatorRuns>& data) {
  AccuracyReport report;
  report.scenario = std::move(scenario);
  report.runs = runs;
  for (const EstimatorRuns& e : data) {
    std::vector<std::string> keys;
    for (const Metrics& m : e.runs) {
      for (const auto& entry : m.entries) detail::addUnique(keys, entry.first);
    }
    detail::sortMetricKeys(keys);
    EstimatorStatistics stats{e.estimator, {}};
    for (const std::string& key : keys) {
      std::vector<double> values;
      for (const Metrics& m : e.runs) {
        if (const auto v = m.get(key)) values.push_back(*v);
      }
      stats.metrics.emplace_back(key, summarize(std::move(values)));
    }
    report.estimators.push_back(std::move(stats));
  }
  return report;
}

AccuracyReport aggregate(std::string scenario, const std::vector<MetricsReport>& runs) {
  std::vector<EstimatorRuns> data;
  for (const MetricsReport& run : runs) {
    for (const EstimatorMetrics& e : run.estimators) {
      auto it = std::find_if(data.begin(), data.end(),
                             [&](const EstimatorRuns& d) { return d.estimator == e.estimator; });
      if (it == data.end()) it = data.insert(data.end(), EstimatorRuns{e.estimator, {}});
      it->runs.push_back(e.metrics);
    }
  }
  return aggregate(std::move(scenario), static_cast<long>(runs.size()), data);
}

std::string formatAccuracyJson(const AccuracyReport& report) {
  using Json = nlohmann::ordered_json;
  auto number = [](double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); };
  Json j = Json::object();
  j["scenario"] = report.scenario;
  j["runs"] = report.runs;
  Json estimators = Json::object();
  for (const EstimatorStatistics& e : report.estimators) {
    Json m = Json::object();
    for (const auto& [key, s] : e.metrics) {
      m[key] = {{"mean", number(s.mean)},
                {"std", number(s.stddev)},
                {"median", number(s.median)},
                {"max", number(s.max)}};
    }
    estimators[e.estimator] = std::move(m);
  }
  j["estimators"] = std::move(estimators);
  return j.dump(2, ' ', false, Json::error_handler_t::replace) + "\n";
}

void writeAccuracyJson(const std::filesystem::path& file, const AccuracyReport& report) {
  io::writeFileAtomically(file, formatAccuracyJson(report));
}

std::string formatAccuracyTable(const AccuracyReport& report) {
  std::vector<std::string> keys;
  for (const EstimatorStatistics& e : report.estimators) {
    for (const auto& entry : e.metrics) detail::addUnique(keys, entry.first);
  }
  detail::sortMetricKeys(keys);
  std::vector<std::vector<std::string>> rows = {{"metric"}};
  for (const EstimatorStatistics& e : report.estimators) rows[0].push_back(e.estimator);
  for (const std::string& key : keys) {
    std::vector<std::string> row = {key};
    for (const EstimatorStatistics& e : report.estimators) {
      const auto it = std::find_if(e.metrics.begin(), e.metrics.end(),
                                   [&](const auto& entry) { return entry.first == key; });
      row.push_back(it == e.metrics.end() ? "-"
                                          : detail::formatValue(it->second.median) + " ± " +
                                                detail::formatValue(it->second.stddev));
    }
    rows.push_back(std::move(row));
  }
  return "scenario " + report.scenario + ", " + std::to_string(report.runs) +
         " runs (median ± sample std)\n" + detail::renderTable(rows);
}

std::string formatAccuracyMarkdown(const AccuracyReport& report) {
  std::vector<std::string> keys;
  for (const EstimatorStatistics& e : report.estimators) {
    for (const auto& entry : e.metrics) detail::addUnique(keys, entry.first);
  }
  detail::sortMetricKeys(keys);
  // Appended piece by piece (GCC 12 reports a false -Wrestrict on "literal" + std::string).
  std::string md = "### ";
  md += report.scenario;
  md += " — ";
  md += std::to_string(report.runs);
  md += " runs, median (mean ± std)\n\n| metric |";
  for (const EstimatorStatistics& e : report.estimators) {
    md += ' ';
    md += e.estimator;
    md += " |";
  }
  md += "\n|---|";
  for (size_t i = 0; i < report.estimators.size(); ++i) md += "---|";
  md += "\n";
  for (const std::string& key : keys) {
    md += "| ";
    md += key;
    md += " |";
    for (const EstimatorStatistics& e : report.estimators) {
      const auto it = std::find_if(e.metrics.begin(), e.metrics.end(),
                                   [&](const auto& entry) { return entry.first == key; });
      md += ' ';
      if (it == e.metrics.end()) {
        md += '-';
      } else {
        md += detail::formatValue(it->second.median);
        md += " (";
        md += detail::formatValue(it->second.mean);
        md += " ± ";
        md += detail::formatValue(it->second.stddev);
        md += ')';
      }
      md += " |";
    }
    md += "\n";
  }
  return md + "\n";
}

}  // namespace traverse::eval
