// metrics.json and its table (../shared/docs/outputs.md).
#include <algorithm>
#include <limits>

#include "eval/table.h"
#include "traverse/eval/json.h"
#include "traverse/eval/metrics.h"

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

void writeDiagnostics(JsonWriter& json, const io::Diagnostics& d) {
  json.key("diagnostics").beginObject();
  json.key("counts").beginObject(/*compact=*/true);
  const auto counts = d.countsByKind();
  for (const std::string& kind : io::kFindingKinds) json.key(kind).integer(counts.at(kind));
  json.endObject();
  long not_used = 0;
  for (const io::Finding& f : d.findings) not_used += f.not_used;
  json.key("samples_not_used").integer(not_used);
  json.key("by_file").beginObject();
  for (const auto& [file, kinds] : d.countsByFile()) {
    json.key(file).beginObject(/*compact=*/true);
    for (const auto& [kind, n] : kinds) json.key(kind).integer(n);
    json.endObject();
  }
  json.endObject();
  json.key("findings").beginArray();
  for (const io::Finding& f : d.findings) {
    json.beginObject(/*compact=*/true);
    json.key("file").string(f.file);
    json.key("kind").string(f.kind);
    json.key("t").number(f.t);
    json.key("duration_s").number(f.duration_s);
    if (!f.column.empty()) {
      json.key("column").string(f.column);
      json.key("value").number(f.value);
    }
    json.key("message").string(f.message);
    if (f.not_used) json.key("not_used").boolean(true);
    json.endObject();
  }
  json.endArray();
  json.endObject();
}

}  // namespace

std::string formatMetricsJson(const MetricsReport& report) {
  JsonWriter json;
  json.beginObject();
  json.key("log").string(report.log);
  if (report.evaluated) {
    json.key("path_length_m").number(report.path_length_m);
    json.key("estimators").beginObject();
    for (const EstimatorMetrics& e : report.estimators) {
      json.key(e.estimator).beginObject();
      for (const auto& [key, value] : e.metrics.entries) json.key(key).number(value);
      json.endObject();
    }
    json.endObject();
  }
  if (report.diagnostics) writeDiagnostics(json, *report.diagnostics);
  json.endObject();
  return json.text();
}

void writeMetricsJson(const std::filesystem::path& file, const MetricsReport& report) {
  writeTextAtomically(file, formatMetricsJson(report));
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
