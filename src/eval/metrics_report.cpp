// metrics.json and its table (../shared/docs/outputs.md).
#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>

#include "eval/table.h"
#include "traverse/core/error.h"
#include "traverse/eval/metrics.h"
#include "traverse/io/atomic_file.h"

#include <nlohmann/json.hpp>

namespace traverse::eval {

std::string estimatorKey(std::string_view trajectory_name) {
  if (trajectory_name == "smoothed") return "smoother";
  return std::string(trajectory_name);
}

MetricsReport evaluateAll(std::string log_name, const std::vector<est::Trajectory>& trajectories,
                          const TruthTrajectory& truth, const EvaluateOptions& options) {
  MetricsReport report;
  report.log = std::move(log_name);
  double t0 = std::numeric_limits<double>::infinity();
  double t1 = -std::numeric_limits<double>::infinity();
  for (const est::Trajectory& tr : trajectories) {
    report.estimators.push_back({estimatorKey(tr.name), evaluate(tr, truth, options)});
    if (tr.nodes.empty()) continue;
    t0 = std::min(t0, tr.nodes.front().t);
    t1 = std::max(t1, tr.nodes.back().t);
  }
  report.path_length_m = t0 <= t1 ? truth.pathLength(t0, t1) : 0.0;
  return report;
}

namespace {

using Json = nlohmann::ordered_json;

/// A number, or null when not finite (JSON has no NaN; a metric that blew up must not read as
/// a number).
Json number(double v) {
  return std::isfinite(v) ? Json(v) : Json(nullptr);
}

Json diagnosticsJson(const io::Diagnostics& d) {
  Json j = Json::object();
  Json counts = Json::object();
  const auto by_kind = d.countsByKind();
  for (const std::string& kind : io::kFindingKinds) counts[kind] = by_kind.at(kind);
  j["counts"] = std::move(counts);
  long not_used = 0;
  for (const io::Finding& f : d.findings) not_used += f.not_used;
  j["samples_not_used"] = not_used;
  Json by_file = Json::object();
  for (const auto& [file, kinds] : d.countsByFile()) {
    Json k = Json::object();
    for (const auto& [kind, n] : kinds) k[kind] = n;
    by_file[file] = std::move(k);
  }
  j["by_file"] = std::move(by_file);
  Json findings = Json::array();
  for (const io::Finding& f : d.findings) {
    Json g = Json::object();
    g["file"] = f.file;
    g["kind"] = f.kind;
    g["t"] = number(f.t);
    g["duration_s"] = number(f.duration_s);
    if (!f.column.empty()) {
      g["column"] = f.column;
      g["value"] = number(f.value);
    }
    g["message"] = f.message;
    if (f.not_used) g["not_used"] = true;
    findings.push_back(std::move(g));
  }
  j["findings"] = std::move(findings);
  return j;
}

/// The number at `key` of object `j`: null reads as NaN; anything else is an InputError.
double readNumber(const Json& j, const std::string& key, const std::string& file) {
  const auto it = j.find(key);
  if (it == j.end()) throw InputError(file, 0, "no \"" + key + "\"");
  if (it->is_null()) return std::numeric_limits<double>::quiet_NaN();
  if (!it->is_number()) throw InputError(file, 0, "\"" + key + "\" is not a number");
  return it->get<double>();
}

std::string readString(const Json& j, const std::string& key, const std::string& file) {
  const auto it = j.find(key);
  if (it == j.end() || !it->is_string())
    throw InputError(file, 0, "\"" + key + "\" is missing or not a string");
  return it->get<std::string>();
}

}  // namespace

std::string formatMetricsJson(const MetricsReport& report) {
  Json j = Json::object();
  j["log"] = report.log;
  if (report.run) {
    const RunSummary& r = *report.run;
    j["run"] = {{"duration_s", number(r.duration_s)},
                {"estimated_path_length_m", number(r.estimated_path_length_m)},
                {"segments", r.segments},
                {"rest_windows", r.rest_windows},
                {"smoother_fallbacks", r.smoother_fallbacks},
                {"slip_updates_gated_pct", number(r.slip_updates_gated_pct)}};
  }
  if (report.evaluated) {
    j["path_length_m"] = number(report.path_length_m);
    Json estimators = Json::object();
    for (const EstimatorMetrics& e : report.estimators) {
      Json m = Json::object();
      for (const auto& [key, value] : e.metrics.entries) m[key] = number(value);
      estimators[e.estimator] = std::move(m);
    }
    j["estimators"] = std::move(estimators);
  }
  if (report.diagnostics) j["diagnostics"] = diagnosticsJson(*report.diagnostics);
  // Invalid UTF-8 (a file name) is replaced, not thrown: the metrics must still be written.
  return j.dump(2, ' ', false, Json::error_handler_t::replace) + "\n";
}

void writeMetricsJson(const std::filesystem::path& file, const MetricsReport& report) {
  io::writeFileAtomically(file, formatMetricsJson(report));
}

MetricsReport parseMetricsJson(const std::string& text, const std::string& file) {
  Json j;
  try {
    j = Json::parse(text);
  } catch (const Json::parse_error& e) {
    throw InputError(file, 0, std::string("not JSON: ") + e.what());
  }
  if (!j.is_object()) throw InputError(file, 0, "not a JSON object");
  MetricsReport report;
  report.log = readString(j, "log", file);
  if (const auto it = j.find("run"); it != j.end() && it->is_object()) {
    RunSummary r;
    r.duration_s = readNumber(*it, "duration_s", file);
    r.estimated_path_length_m = readNumber(*it, "estimated_path_length_m", file);
    r.segments = static_cast<int>(readNumber(*it, "segments", file));
    r.rest_windows = static_cast<int>(readNumber(*it, "rest_windows", file));
    r.smoother_fallbacks = static_cast<int>(readNumber(*it, "smoother_fallbacks", file));
    r.slip_updates_gated_pct = readNumber(*it, "slip_updates_gated_pct", file);
    report.run = r;
  }
  const auto est = j.find("estimators");
  report.evaluated = est != j.end();
  if (report.evaluated) {
    report.path_length_m = readNumber(j, "path_length_m", file);
    if (!est->is_object()) throw InputError(file, 0, "\"estimators\" is not an object");
    for (const auto& [name, values] : est->items()) {
      if (!values.is_object())
        throw InputError(file, 0, "\"estimators\"." + name + " is not an object");
      Metrics m;
      for (const auto& [key, v] : values.items()) m.set(key, readNumber(values, key, file));
      report.estimators.push_back({name, std::move(m)});
    }
  }
  if (const auto d = j.find("diagnostics"); d != j.end()) {
    io::Diagnostics diagnostics;
    const auto f = d->find("findings");
    if (f == d->end() || !f->is_array())
      throw InputError(file, 0, "\"diagnostics\" has no \"findings\" array");
    for (const Json& g : *f) {
      if (!g.is_object()) throw InputError(file, 0, "a finding is not an object");
      io::Finding finding;
      finding.file = readString(g, "file", file);
      finding.kind = readString(g, "kind", file);
      finding.t = readNumber(g, "t", file);
      finding.duration_s = readNumber(g, "duration_s", file);
      if (g.contains("column")) {
        finding.column = readString(g, "column", file);
        finding.value = readNumber(g, "value", file);
      }
      finding.message = readString(g, "message", file);
      finding.not_used = g.value("not_used", false);
      diagnostics.findings.push_back(std::move(finding));
    }
    report.diagnostics = std::move(diagnostics);
  }
  return report;
}

MetricsReport readMetricsJson(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file.string(), 0, "cannot open");
  return parseMetricsJson(std::string(std::istreambuf_iterator<char>(in), {}), file.string());
}

std::string formatMetricsTable(const MetricsReport& report) {
  std::vector<std::string> keys;
  for (const EstimatorMetrics& e : report.estimators) {
    for (const auto& entry : e.metrics.entries) detail::addUnique(keys, entry.first);
  }
  detail::sortMetricKeys(keys);
  std::vector<std::vector<std::string>> rows = {{"metric"}};
  for (const EstimatorMetrics& e : report.estimators) rows[0].push_back(e.estimator);
  for (const std::string& key : keys) {
    std::vector<std::string> row = {key};
    for (const EstimatorMetrics& e : report.estimators) {
      const auto v = e.metrics.get(key);
      row.push_back(v ? detail::formatValue(*v) : "-");
    }
    rows.push_back(std::move(row));
  }
  return "log " + report.log + ", true path length " + detail::formatValue(report.path_length_m) +
         " m\n" + detail::renderTable(rows);
}

}  // namespace traverse::eval
