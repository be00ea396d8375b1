// A small plot writer for report.html: one inline <svg> per plot, no library, no network
// (docs/report.md says why). The data area is a nested <svg class="data"> whose viewBox is in
// data units (y negated: SVG's y grows downwards), so the report's script zooms and pans by
// changing that viewBox alone, and every stroke is non-scaling; the same script draws the axis
// ticks and grid for the current view. Series are decimated for drawing only (min and max per
// bucket, so a spike survives); the numbers in the CSVs are never touched.
#pragma once

#include <string>
#include <vector>

namespace traverse::report {

struct Series {
  std::string name, color;
  std::vector<double> x, y;  ///< a non-finite value breaks the line
  bool dashed = false;
  bool dots = false;  ///< points instead of a line
  double width = 1.5;
};

/// A filled envelope lo(x) … hi(x) (±3σ), drawn under the lines.
struct Band {
  std::string name, color;
  std::vector<double> x, lo, hi;
};

/// Points with vertical error bars y ± err.
struct ErrorBars {
  std::string name, color;
  std::vector<double> x, y, err;
};

/// A shaded stretch of x (a rest window).
struct Span {
  double x0 = 0.0, x1 = 0.0;
};

struct Plot {
  std::string title, x_label, y_label;
  bool equal_aspect = false;  ///< one metre is as long on both axes (the top view)
  int width = 900, height = 280;
  std::vector<Band> bands;
  std::vector<Span> spans;
  std::string span_name = "rest";  ///< the legend entry of the spans
  std::vector<double> vlines;      ///< thin vertical lines (segment boundaries)
  std::string vline_name = "segment boundary";
  std::vector<Series> series;
  std::vector<ErrorBars> bars;
  std::string note;  ///< one line under the title (what is shown, how aligned)
};

/// At most `max_points` points of (x, y) in x order keeping each bucket's minimum and maximum of
/// y (in their order), so the drawn line has the original's extremes. Non-finite y are kept as
/// line breaks. Returns the indices kept.
std::vector<size_t> decimationIndices(const std::vector<double>& x, const std::vector<double>& y,
                                      size_t max_points);

/// Decimates every series, band and error-bar set of `plot` to at most `max_points` points.
void decimate(Plot& plot, size_t max_points);

/// The <svg class="plot"> element of the plot (no XML declaration: it lives inside HTML).
/// Numbers are written with 6 significant digits. An empty plot (no finite point) gets a note
/// "no data" instead of axes.
std::string renderSvg(const Plot& plot);

/// The script that draws ticks and grids and gives every plot zoom (wheel: x; shift+wheel: y;
/// the top view both), pan (drag) and reset (double click). It sets data-plots on <html> to the
/// number of plots drawn and data-errors to the number of script errors caught.
const std::string& plotScript();

/// The CSS the plots need.
const std::string& plotStyle();

/// Text escaped for HTML element content and attribute values.
std::string htmlEscape(const std::string& text);

}  // namespace traverse::report
