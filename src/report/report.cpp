#include "traverse/report/report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>

#include "traverse/core/so3.h"
#include "traverse/eval/alignment.h"
#include "traverse/eval/position_truth.h"
#include "traverse/eval/truth.h"
#include "traverse/io/atomic_file.h"
#include "traverse/report/svg_plot.h"

namespace traverse::report {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
constexpr double kRadPerSToDegPerH = kRadToDeg * 3600.0;

std::string fmt(double v, int digits = 4) {
  if (!std::isfinite(v)) return "–";
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

std::string colorOf(const std::string& name) {
  if (name == "dr") return "#e67e22";
  if (name == "ekf") return "#1f77b4";
  if (name == "rts") return "#9467bd";
  return "#2ca02c";  // smoothed
}

std::string labelOf(const std::string& name) {
  if (name == "dr") return "DR";
  if (name == "ekf") return "EKF";
  if (name == "rts") return "RTS";
  if (name == "smoothed") return "smoother";
  return name;
}

const char* kWheelColors[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                              "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};

/// The node nearest in time to t (nodes sorted by t).
const est::TrajectoryNode* nodeAt(const est::Trajectory& tr, double t) {
  if (tr.nodes.empty()) return nullptr;
  auto it = std::lower_bound(tr.nodes.begin(), tr.nodes.end(), t,
                             [](const est::TrajectoryNode& n, double v) { return n.t < v; });
  if (it == tr.nodes.end()) return &tr.nodes.back();
  if (it != tr.nodes.begin() && t - std::prev(it)->t < it->t - t) --it;
  return &*it;
}

/// Per estimator: errors (or σ) per axis over time, with their σ.
struct AxisSeries {
  std::vector<double> t;
  std::array<std::vector<double>, 3> err, sigma;
};

/// What the log's truth lets the report show.
struct TruthView {
  enum class Kind { kNone, kPose, kFixes } kind = Kind::kNone;
  std::optional<eval::TruthTrajectory> pose;
  std::optional<eval::PositionTruth> fixes;
  /// Per trajectory: the posyaw alignment to the fixes (identity for pose truth).
  std::map<std::string, eval::PosYawAlignment> alignment;
  /// Per trajectory against fixes: the pairing and the start-pinned errors (the consistency
  /// metrics' gauge, eval::startPinnedErrors), computed once with the alignment above.
  std::map<std::string, std::pair<eval::FixPairs, eval::StartPinnedErrors>> pinned;
};

std::string table(const std::vector<std::vector<std::string>>& rows, bool header = true) {
  std::string h = "<table>";
  for (size_t r = 0; r < rows.size(); ++r) {
    h += "<tr>";
    for (const std::string& c : rows[r]) {
      const bool th = header && r == 0;
      h += (th ? "<th>" : "<td>") + htmlEscape(c) + (th ? "</th>" : "</td>");
    }
    h += "</tr>";
  }
  return h + "</table>";
}

class Builder {
 public:
  explicit Builder(const ReportInput& in) : in_(in), log_(*in.log) {
    for (const est::Trajectory* tr : in_.trajectories) {
      if (tr && !tr->nodes.empty()) trajectories_.push_back(tr);
    }
    for (const est::Trajectory* tr : trajectories_) {
      if (tr->name == "smoothed") best_ = tr;
    }
    if (!best_) {
      for (const est::Trajectory* tr : trajectories_)
        if (tr->name == "ekf") best_ = tr;
    }
    if (!best_ && !trajectories_.empty()) best_ = trajectories_.back();
    setUpTruth();
  }

  std::string html() {
    std::string body;
    body += "<h1>traverse report: " + htmlEscape(in_.log_name) + "</h1>";
    if (!in_.command.empty())
      body += "<p class=\"cmd\"><code>" + htmlEscape(in_.command) + "</code></p>";
    body += "<p>" + htmlEscape(truthSentence()) +
            " Plots: wheel zooms time (shift+wheel: the vertical axis; the top view both), drag "
            "pans, double click resets. Plotted series are decimated to at most " +
            std::to_string(in_.max_points) +
            " points each (keeping every bucket's extremes); the CSVs hold every row.</p>";
    body += "<nav>" + nav() + "</nav>";
    body += section("metrics", "Metrics", metricsSection());
    body += section("track", "Top view", plot(topView()));
    body += section("elevation", "Elevation", plot(elevation()));
    body +=
        section("position", truth_.kind == TruthView::Kind::kNone ? "Position σ" : "Position error",
                positionPlots());
    body +=
        section("attitude", truth_.kind == TruthView::Kind::kPose ? "Attitude error" : "Attitude σ",
                attitudePlots());
    body += section("contact", "Contact angles", plot(contactAngles()));
    body += section("bias", "Gyro bias per segment", biasPlots());
    body += section("segments", "Segments and solver", segmentsTable());
    body += section("log", "Log, diagnostics and run", logSection());
    return "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta "
           "charset=\"utf-8\">\n<title>traverse: " +
           htmlEscape(in_.log_name) + "</title>\n<style>\n" + pageStyle() + plotStyle() +
           "</style>\n</head>\n<body>\n" + body + "\n<script>\n" + plotScript() +
           "</script>\n</body>\n</html>\n";
  }

  int plots() const { return plots_; }

 private:
  static const std::string& pageStyle() {
    static const std::string css =
        R"(body{font:14px/1.4 sans-serif;margin:16px 24px;color:#222;max-width:1000px}
h1{font-size:20px;margin:4px 0}h2{font-size:16px;margin:22px 0 6px;border-bottom:1px solid #ddd}
nav a{margin-right:12px}table{border-collapse:collapse;font-size:12px;margin:6px 0}
td,th{border:1px solid #ddd;padding:2px 6px;text-align:right}th{background:#f4f4f4}
td:first-child,th:first-child{text-align:left}code,pre{font-size:12px}pre{background:#f8f8f8;padding:6px;overflow-x:auto}
p.cmd{color:#555}.warn{color:#a40}
)";
    return css;
  }

  std::string nav() const {
    std::string n;
    for (const auto& [id, title] :
         std::vector<std::pair<std::string, std::string>>{{"metrics", "metrics"},
                                                          {"track", "top view"},
                                                          {"elevation", "elevation"},
                                                          {"position", "position"},
                                                          {"attitude", "attitude"},
                                                          {"contact", "contact angles"},
                                                          {"bias", "gyro bias"},
                                                          {"segments", "segments"},
                                                          {"log", "log and diagnostics"}})
      n += "<a href=\"#" + id + "\">" + title + "</a>";
    return n;
  }

  static std::string section(const std::string& id, const std::string& title,
                             const std::string& content) {
    return "<section id=\"" + id + "\"><h2>" + htmlEscape(title) + "</h2>" + content +
           "</section>\n";
  }

  std::string plot(Plot p) {
    decimate(p, in_.max_points);
    ++plots_;
    return renderSvg(p);
  }

  void setUpTruth() {
    if (log_.truth) {
      try {
        truth_.pose.emplace(*log_.truth);
        truth_.kind = TruthView::Kind::kPose;
      } catch (const std::exception&) {
      }
    } else if (log_.gps && !log_.gps->empty()) {
      try {
        truth_.fixes.emplace(*log_.gps, log_.config.gps.antenna_body_m);
        truth_.kind = TruthView::Kind::kFixes;
        for (const est::Trajectory* tr : trajectories_) {
          const eval::FixPairs pairs = eval::pairWithFixes(*tr, *truth_.fixes);
          if (pairs.t.size() < 2) continue;
          // As the evaluation: the whole-track robust alignment (the views) and its inliers,
          // which pin the start-pinned gauge (the error plots).
          const eval::PositionTruthOptions options;
          const eval::WholeTrackAlignment fit = eval::alignWholeTrack(pairs, options);
          truth_.alignment[tr->name] = fit.whole.alignment;
          eval::StartPinnedErrors e =
              eval::startPinnedErrors(pairs, *truth_.fixes, fit.inlier, options.start_span_m);
          truth_.pinned[tr->name] = {pairs, std::move(e)};
        }
      } catch (const std::exception&) {
        truth_.kind = TruthView::Kind::kNone;
      }
    }
  }

  std::string truthSentence() const {
    switch (truth_.kind) {
      case TruthView::Kind::kPose:
        return "Truth: truth.csv (position and attitude); errors are estimate − truth in the "
               "site frame, envelopes ±3σ of each estimator's own covariance.";
      case TruthView::Kind::kFixes:
        return "Truth: gps.csv (position fixes). The views align each estimate to the fixes "
               "by yaw and translation over the whole track (the posyaw alignment of "
               "ate_posyaw_m); the error plots compare its antenna in its own start-pinned "
               "gauge, with envelopes ±3σ of its covariance plus the fix's and the pin's σ.";
      case TruthView::Kind::kNone:
        break;
    }
    return "No truth in this log: the plots show the estimates and their σ, no errors.";
  }

  Vec3d placed(const est::Trajectory& tr, const Vec3d& p) const {
    const auto it = truth_.alignment.find(tr.name);
    return it == truth_.alignment.end() ? p : it->second.apply(p);
  }

  void markSegments(Plot& p) const {
    if (!in_.segmentation) return;
    for (const est::RestWindow& r : in_.segmentation->rests)
      p.spans.push_back({r.t_start, r.t_end});
    for (const est::Segment& s : in_.segmentation->segments) {
      if (s.kind == est::Segment::Kind::kMotion) p.vlines.push_back(s.t_start);
    }
  }

  Plot topView() const {
    Plot p;
    p.title = "Top view";
    p.x_label = "x (m, site)";
    p.y_label = "y (m, site)";
    p.equal_aspect = true;
    p.height = 560;
    if (truth_.kind == TruthView::Kind::kFixes)
      p.note = "estimates aligned to the GPS fixes by yaw and translation";
    if (truth_.kind == TruthView::Kind::kPose) {
      Series s{"truth", "#000000", {}, {}, false, false, 2.5};
      for (Eigen::Index i = 0; i < log_.truth->size(); ++i) {
        s.x.push_back(log_.truth->values(i, 0));
        s.y.push_back(log_.truth->values(i, 1));
      }
      p.series.push_back(std::move(s));
    } else if (truth_.kind == TruthView::Kind::kFixes) {
      Series s{"GPS fixes", "#9a9a9a", {}, {}, false, true, 3.0};
      for (const eval::PositionFix& f : truth_.fixes->fixes())
        s.x.push_back(f.p_site.x()), s.y.push_back(f.p_site.y());
      p.series.push_back(std::move(s));
    }
    for (const est::Trajectory* tr : trajectories_) {
      Series s{labelOf(tr->name), colorOf(tr->name), {}, {}, false, false, 1.5};
      for (const est::TrajectoryNode& n : tr->nodes) {
        const Vec3d q = placed(*tr, n.p_site);
        s.x.push_back(q.x()), s.y.push_back(q.y());
      }
      p.series.push_back(std::move(s));
    }
    if (best_ && in_.segmentation) {
      Series starts{"segment start", "#c0392b", {}, {}, false, true, 7.0};
      Series rests{"rest window", "#34495e", {}, {}, false, true, 9.0};
      for (const est::Segment& s : in_.segmentation->segments) {
        const est::TrajectoryNode* n = nodeAt(*best_, s.t_start);
        if (!n) continue;
        const Vec3d q = placed(*best_, n->p_site);
        Series& into = s.kind == est::Segment::Kind::kMotion ? starts : rests;
        into.x.push_back(q.x()), into.y.push_back(q.y());
      }
      p.series.push_back(std::move(rests));
      p.series.push_back(std::move(starts));
    }
    return p;
  }

  Plot elevation() const {
    Plot p;
    p.title = "Elevation";
    p.x_label = "t (s)";
    p.y_label = "z (m, site)";
    if (truth_.kind == TruthView::Kind::kPose) {
      Series s{"truth", "#000000", {}, {}, false, false, 2.5};
      for (Eigen::Index i = 0; i < log_.truth->size(); ++i)
        s.x.push_back(log_.truth->t[i]), s.y.push_back(log_.truth->values(i, 2));
      p.series.push_back(std::move(s));
    } else if (truth_.kind == TruthView::Kind::kFixes) {
      Series s{"GPS fixes (antenna)", "#9a9a9a", {}, {}, false, true, 3.0};
      for (const eval::PositionFix& f : truth_.fixes->fixes())
        s.x.push_back(f.t), s.y.push_back(f.p_site.z());
      p.series.push_back(std::move(s));
      p.note = "estimates aligned to the fixes; the fixes are the antenna's height";
    }
    for (const est::Trajectory* tr : trajectories_) {
      Series s{labelOf(tr->name), colorOf(tr->name), {}, {}, false, false, 1.5};
      for (const est::TrajectoryNode& n : tr->nodes)
        s.x.push_back(n.t), s.y.push_back(placed(*tr, n.p_site).z());
      p.series.push_back(std::move(s));
    }
    markSegments(p);
    return p;
  }

  /// Position error per axis with its σ (or the σ alone without truth), per trajectory.
  std::map<std::string, AxisSeries> positionErrors() const {
    std::map<std::string, AxisSeries> out;
    for (const est::Trajectory* tr : trajectories_) {
      AxisSeries a;
      if (truth_.kind == TruthView::Kind::kPose) {
        for (const est::TrajectoryNode& n : tr->nodes) {
          if (n.t < truth_.pose->tStart() || n.t > truth_.pose->tEnd()) continue;
          const Vec3d e = n.p_site - truth_.pose->position(n.t);
          a.t.push_back(n.t);
          for (int i = 0; i < 3; ++i) {
            a.err[i].push_back(e[i]);
            a.sigma[i].push_back(tr->has_covariance ? std::sqrt(n.covariance(i, i)) : NAN);
          }
        }
      } else if (truth_.kind == TruthView::Kind::kFixes) {
        // In the estimate's own gauge, as the consistency metrics: pinned at the start, so
        // that the ±3σ envelope (σ ≈ 0 at the start) describes the error plotted.
        const auto it = truth_.pinned.find(tr->name);
        if (it == truth_.pinned.end() || !it->second.second.valid) continue;
        const eval::FixPairs& pairs = it->second.first;
        const eval::StartPinnedErrors& pinned = it->second.second;
        for (size_t k = 0; k < pairs.t.size(); ++k) {
          a.t.push_back(pairs.t[k]);
          for (int i = 0; i < 3; ++i) {
            a.err[i].push_back(pinned.error[k][i]);
            a.sigma[i].push_back(
                k < pinned.covariance.size() ? std::sqrt(pinned.covariance[k](i, i)) : NAN);
          }
        }
      } else {
        if (!tr->has_covariance) continue;
        for (const est::TrajectoryNode& n : tr->nodes) {
          a.t.push_back(n.t);
          for (int i = 0; i < 3; ++i) {
            a.err[i].push_back(NAN);
            a.sigma[i].push_back(std::sqrt(n.covariance(i, i)));
          }
        }
      }
      out[tr->name] = std::move(a);
    }
    return out;
  }

  /// Three plots (one per axis) of error with ±3σ bands, or of σ without truth.
  std::string axisPlots(const std::map<std::string, AxisSeries>& data,
                        const std::array<std::string, 3>& axis, const std::string& unit,
                        double scale, bool errors) {
    std::string html;
    for (int i = 0; i < 3; ++i) {
      Plot p;
      p.title = (errors ? "Error in " : "1σ of ") + axis[i] + (errors ? ", with ±3σ" : "");
      p.x_label = "t (s)";
      p.y_label = axis[i] + " (" + unit + ")";
      p.height = 240;
      for (const est::Trajectory* tr : trajectories_) {
        const auto it = data.find(tr->name);
        if (it == data.end()) continue;
        const AxisSeries& a = it->second;
        if (errors) {
          Band b{"±3σ " + labelOf(tr->name), colorOf(tr->name), a.t, {}, {}};
          bool any = false;
          for (size_t k = 0; k < a.t.size(); ++k) {
            const double s = 3.0 * scale * a.sigma[i][k];
            any = any || std::isfinite(s);
            b.lo.push_back(-s), b.hi.push_back(s);
          }
          if (any) p.bands.push_back(std::move(b));
          Series s{labelOf(tr->name), colorOf(tr->name), a.t, {}, false, false, 1.5};
          for (double v : a.err[i]) s.y.push_back(scale * v);
          p.series.push_back(std::move(s));
        } else {
          Series s{labelOf(tr->name), colorOf(tr->name), a.t, {}, false, false, 1.5};
          for (double v : a.sigma[i]) s.y.push_back(scale * v);
          p.series.push_back(std::move(s));
        }
      }
      markSegments(p);
      html += plot(std::move(p));
    }
    return html;
  }

  std::string positionPlots() {
    const bool errors = truth_.kind != TruthView::Kind::kNone;
    std::string note;
    if (truth_.kind == TruthView::Kind::kFixes)
      note =
          "<p>At the GPS fix times, antenna position in the estimate's own gauge: pinned by "
          "the fixes of the first 0.5 m of track, yaw fitted about that point (the gauge of "
          "nees_position_mean and position_rmse_over_sigma); the ±3σ envelope is the "
          "estimate's covariance, the fix's σ and the pin's. Fixes the evaluation rejects as "
          "outliers are shown too.</p>";
    return note + axisPlots(positionErrors(), {"x", "y", "z"}, "m", 1.0, errors);
  }

  std::string attitudePlots() {
    std::map<std::string, AxisSeries> data;
    const bool errors = truth_.kind == TruthView::Kind::kPose;
    for (const est::Trajectory* tr : trajectories_) {
      if (!errors && !tr->has_covariance) continue;
      AxisSeries a;
      for (const est::TrajectoryNode& n : tr->nodes) {
        Vec3d e = Vec3d::Constant(NAN);
        if (errors) {
          if (n.t < truth_.pose->tStart() || n.t > truth_.pose->tEnd()) continue;
          e = so3::boxminus(n.q_site_body, truth_.pose->attitude(n.t));
        }
        a.t.push_back(n.t);
        for (int i = 0; i < 3; ++i) {
          a.err[i].push_back(e[i]);
          a.sigma[i].push_back(tr->has_covariance ? std::sqrt(n.covariance(3 + i, 3 + i)) : NAN);
        }
      }
      data[tr->name] = std::move(a);
    }
    std::string note = errors ? "<p>Body-frame small-angle error Log(q_true⁻¹ q̂) about x "
                                "(roll), y (pitch), z (yaw).</p>"
                              : "<p>No attitude truth: the σ of each estimator (body-frame small "
                                "angles).</p>";
    return note + axisPlots(data, {"roll (x)", "pitch (y)", "yaw (z)"}, "deg", kRadToDeg, errors);
  }

  Plot contactAngles() const {
    Plot p;
    p.title = "Contact angles";
    p.x_label = "t (s)";
    p.y_label = "ξ (deg)";
    const est::Trajectory* tr = best_;
    if (tr) {
      p.note = "the " + labelOf(tr->name) + "'s ξ per wheel" +
               (truth_.pose && truth_.pose->hasContactAngles() ? "; truth dashed" : "");
      const int wheels = static_cast<int>(tr->nodes.front().xi.size());
      for (int w = 0; w < wheels; ++w) {
        const std::string color = kWheelColors[w % 10];
        Series s{"wheel " + std::to_string(w + 1), color, {}, {}, false, false, 1.2};
        for (const est::TrajectoryNode& n : tr->nodes)
          s.x.push_back(n.t), s.y.push_back(kRadToDeg * n.xi[w]);
        p.series.push_back(std::move(s));
        if (truth_.pose && truth_.pose->hasContactAngles()) {
          Series t{"", color, {}, {}, true, false, 1.0};
          for (Eigen::Index i = 0; i < log_.truth->size(); ++i) {
            const double ti = log_.truth->t[i];
            const auto xi = truth_.pose->contactAngles(ti);
            if (w >= xi.size()) break;
            t.x.push_back(ti), t.y.push_back(kRadToDeg * xi[w]);
          }
          p.series.push_back(std::move(t));
        }
      }
    }
    markSegments(p);
    return p;
  }

  std::string biasPlots() {
    const bool three_axis = log_.gyro.values.cols() >= 3;
    std::string html =
        "<p>Motion segments: the smoother's bias per leg (else the EKF's); rest windows: the "
        "window's own measurement (mean gyro). Bars ±1σ. °/h.</p>";
    const char* names[] = {"x", "y", "z"};
    for (int axis = three_axis ? 0 : 2; axis < 3; ++axis) {
      Plot p;
      p.title = std::string("Gyro bias, ") + names[axis] + " axis";
      p.x_label = "t (s)";
      p.y_label = std::string("b") + names[axis] + " (°/h)";
      p.height = 240;
      ErrorBars motion{"motion segment", "#2ca02c", {}, {}, {}},
          rest{"rest window", "#34495e", {}, {}, {}};
      for (const est::SegmentRow& r : in_.segments) {
        if (!std::isfinite(r.bias[axis]) || (r.bias[axis] == 0.0 && r.sigma_bias[axis] == 0.0))
          continue;
        ErrorBars& into = r.kind == est::Segment::Kind::kMotion ? motion : rest;
        into.x.push_back(0.5 * (r.t_start + r.t_end));
        into.y.push_back(kRadPerSToDegPerH * r.bias[axis]);
        into.err.push_back(kRadPerSToDegPerH * r.sigma_bias[axis]);
      }
      p.bars.push_back(std::move(rest));
      p.bars.push_back(std::move(motion));
      if (truth_.pose && truth_.pose->hasBias()) {
        Series s{"truth", "#000000", {}, {}, true, false, 1.2};
        for (Eigen::Index i = 0; i < log_.truth->size(); ++i) {
          const double ti = log_.truth->t[i];
          s.x.push_back(ti), s.y.push_back(kRadPerSToDegPerH * truth_.pose->bias(ti)[axis]);
        }
        p.series.push_back(std::move(s));
      }
      markSegments(p);
      html += plot(std::move(p));
    }
    return html;
  }

  std::string metricsSection() const {
    std::string h;
    const eval::MetricsReport* m = in_.metrics;
    if (m && m->run) {
      const eval::RunSummary& r = *m->run;
      h += table({{"log span (s)", "estimated path (m)", "true path (m)", "segments",
                   "rest windows", "smoother fallbacks", "slip updates gated (%)"},
                  {fmt(r.duration_s), fmt(r.estimated_path_length_m),
                   m->evaluated ? fmt(m->path_length_m) : "–", std::to_string(r.segments),
                   std::to_string(r.rest_windows), std::to_string(r.smoother_fallbacks),
                   fmt(r.slip_updates_gated_pct, 3)}});
    }
    if (!m || !m->evaluated || m->estimators.empty())
      return h + "<p>No truth: nothing to evaluate (docs/evaluation.md).</p>";
    std::vector<std::string> keys;
    for (const eval::EstimatorMetrics& e : m->estimators) {
      for (const auto& [k, v] : e.metrics.entries) {
        if (std::find(keys.begin(), keys.end(), k) == keys.end()) keys.push_back(k);
      }
    }
    std::sort(keys.begin(), keys.end());
    std::vector<std::vector<std::string>> rows = {{"metric"}};
    for (const eval::EstimatorMetrics& e : m->estimators) rows[0].push_back(e.estimator);
    for (const std::string& k : keys) {
      std::vector<std::string> row = {k};
      for (const eval::EstimatorMetrics& e : m->estimators) {
        const auto v = e.metrics.get(k);
        row.push_back(v ? fmt(*v) : "–");
      }
      rows.push_back(std::move(row));
    }
    return h + table(rows) + "<p>Definitions: docs/evaluation.md.</p>";
  }

  std::string segmentsTable() const {
    const bool three_axis = log_.gyro.values.cols() >= 3;
    std::vector<std::vector<std::string>> rows = {{"segment", "kind", "t start (s)", "t end (s)"}};
    const char* names[] = {"x", "y", "z"};
    for (int a = three_axis ? 0 : 2; a < 3; ++a)
      rows[0].push_back(std::string("b") + names[a] + " ± σ (°/h)");
    for (const char* c : {"status", "iterations", "final cost", "solve (s)"}) rows[0].push_back(c);
    for (const est::SegmentRow& r : in_.segments) {
      std::vector<std::string> row = {std::to_string(r.segment),
                                      r.kind == est::Segment::Kind::kMotion ? "motion" : "rest",
                                      fmt(r.t_start, 6), fmt(r.t_end, 6)};
      for (int a = three_axis ? 0 : 2; a < 3; ++a)
        row.push_back(fmt(kRadPerSToDegPerH * r.bias[a]) + " ± " +
                      fmt(kRadPerSToDegPerH * r.sigma_bias[a], 2));
      row.push_back(r.status);
      row.push_back(r.iterations ? std::to_string(*r.iterations) : "");
      row.push_back(r.final_cost ? fmt(*r.final_cost) : "");
      row.push_back(r.solve_seconds ? fmt(*r.solve_seconds, 3) : "");
      rows.push_back(std::move(row));
    }
    return table(rows);
  }

  std::string logSection() const {
    std::string h = "<p>Rover <b>" + htmlEscape(log_.config.name) + "</b>, " +
                    std::to_string(log_.geometry.wheels.size()) + " wheels; log " +
                    htmlEscape(log_.dir.string()) + "</p>";
    std::vector<std::vector<std::string>> rows = {
        {"file", "rows", "columns", "rate (Hz)", "first t (s)", "last t (s)"}};
    for (const io::NamedStream& s : io::logStreams(log_)) {
      if (!s.stream) continue;
      std::string cols = "t";
      for (const std::string& c : s.stream->columns) cols += "," + c;
      const double period = io::medianPeriod(*s.stream);
      rows.push_back({s.file, std::to_string(s.stream->size()), cols,
                      period > 0 ? fmt(1.0 / period) : "–",
                      s.stream->empty() ? "–" : fmt(s.stream->t[0], 8),
                      s.stream->empty() ? "–" : fmt(s.stream->t[s.stream->size() - 1], 8)});
    }
    h += table(rows);
    const eval::MetricsReport* m = in_.metrics;
    if (m && m->diagnostics) {
      const auto counts = m->diagnostics->countsByKind();
      std::vector<std::vector<std::string>> c = {{"finding"}, {"count"}};
      for (const std::string& kind : io::kFindingKinds) {
        c[0].push_back(kind);
        c[1].push_back(std::to_string(counts.at(kind)));
      }
      h += "<h3>Diagnostics</h3>" + table(c);
      const auto& f = m->diagnostics->findings;
      if (f.empty()) {
        h += "<p>No findings: the streams are clean.</p>";
      } else {
        h += "<pre>";
        const size_t shown = std::min<size_t>(f.size(), 500);
        for (size_t i = 0; i < shown; ++i) h += htmlEscape(f[i].file + ": " + f[i].message) + "\n";
        if (shown < f.size())
          h += std::to_string(f.size() - shown) + " more (metrics.json lists them all)\n";
        h += "</pre>";
      }
    }
    if (!in_.run_lines.empty()) {
      h += "<h3>What the run said</h3><pre>";
      for (const std::string& l : in_.run_lines) h += htmlEscape(l) + "\n";
      h += "</pre>";
    }
    return h;
  }

  const ReportInput& in_;
  const io::TraverseLog& log_;
  std::vector<const est::Trajectory*> trajectories_;
  const est::Trajectory* best_ = nullptr;
  TruthView truth_;
  int plots_ = 0;
};

}  // namespace

std::string renderReport(const ReportInput& input) {
  if (!input.log) throw std::invalid_argument("renderReport: no log");
  Builder b(input);
  return b.html();
}

void writeReport(const std::filesystem::path& file, const ReportInput& input) {
  io::writeFileAtomically(file, renderReport(input));
}

}  // namespace traverse::report
