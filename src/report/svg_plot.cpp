#include "traverse/report/svg_plot.h"

// GCC 12 at -O3 reports a false -Wrestrict inside std::string's operator+ ("literal" + string
// rvalue; GCC bug 105329), which this file's SVG text building is made of.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wrestrict"
#endif

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>

namespace traverse::report {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

struct Range {
  double lo = kInf, hi = -kInf;
  void add(double v) {
    if (!std::isfinite(v)) return;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  bool valid() const { return lo <= hi; }
  /// Padded by `pad` of the span; a zero span is widened to ±1 % of the value (or ±1).
  Range padded(double pad) const {
    Range r = *this;
    double span = hi - lo;
    if (span <= 0.0) {
      const double half = std::abs(lo) > 0 ? 0.01 * std::abs(lo) : 1.0;
      r.lo -= half, r.hi += half;
      span = r.hi - r.lo;
    }
    r.lo -= pad * span, r.hi += pad * span;
    return r;
  }
};

/// "M x y x y …", a new "M" after every non-finite point.
std::string pathData(const std::vector<double>& x, const std::vector<double>& y) {
  std::string d;
  bool pen = false;
  for (size_t i = 0; i < x.size() && i < y.size(); ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) {
      pen = false;
      continue;
    }
    d += pen ? " " : (d.empty() ? "M" : " M");
    d += num(x[i]) + " " + num(-y[i]);
    pen = true;
  }
  return d;
}

/// Zero-length subpaths: with round caps each is a dot of the stroke's width.
std::string dotData(const std::vector<double>& x, const std::vector<double>& y) {
  std::string d;
  for (size_t i = 0; i < x.size() && i < y.size(); ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) continue;
    d += (d.empty() ? "M" : " M") + num(x[i]) + " " + num(-y[i]) + "h0";
  }
  return d;
}

template <typename T>
std::vector<T> pick(const std::vector<T>& v, const std::vector<size_t>& idx) {
  std::vector<T> out;
  out.reserve(idx.size());
  for (size_t i : idx) out.push_back(v[i]);
  return out;
}

}  // namespace

std::vector<size_t> decimationIndices(const std::vector<double>& x, const std::vector<double>& y,
                                      size_t max_points) {
  const size_t n = std::min(x.size(), y.size());
  std::vector<size_t> all(n);
  std::iota(all.begin(), all.end(), 0);
  if (n <= max_points || max_points < 4) return all;
  const size_t buckets = max_points / 2;
  std::vector<size_t> out;
  out.reserve(max_points + 2);
  for (size_t b = 0; b < buckets; ++b) {
    const size_t i0 = b * n / buckets, i1 = (b + 1) * n / buckets;
    size_t lo = i0, hi = i0;
    bool finite = false, gap = false;
    for (size_t i = i0; i < i1; ++i) {
      if (!std::isfinite(y[i])) {
        gap = true;
        continue;
      }
      if (!finite) {
        lo = hi = i;
        finite = true;
      } else {
        if (y[i] < y[lo]) lo = i;
        if (y[i] > y[hi]) hi = i;
      }
    }
    if (!finite) {
      out.push_back(i0);  // a stretch of nothing: keep the break
      continue;
    }
    if (gap) {  // keep one break inside the bucket so the line does not bridge it
      for (size_t i = i0; i < i1; ++i)
        if (!std::isfinite(y[i])) {
          out.push_back(i);
          break;
        }
    }
    out.push_back(std::min(lo, hi));
    if (hi != lo) out.push_back(std::max(lo, hi));
  }
  out.push_back(0);
  out.push_back(n - 1);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

void decimate(Plot& plot, size_t max_points) {
  for (Series& s : plot.series) {
    const auto idx = decimationIndices(s.x, s.y, max_points);
    s.x = pick(s.x, idx), s.y = pick(s.y, idx);
  }
  for (Band& b : plot.bands) {
    // Bucket by bucket: the lowest lo and the highest hi, so the envelope only grows.
    const size_t n = b.x.size();
    if (n <= max_points) continue;
    const size_t buckets = max_points / 2;
    std::vector<double> x, lo, hi;
    for (size_t k = 0; k < buckets; ++k) {
      const size_t i0 = k * n / buckets, i1 = (k + 1) * n / buckets;
      double l = kInf, h = -kInf;
      bool any = false;
      for (size_t i = i0; i < i1; ++i) {
        if (!std::isfinite(b.lo[i]) || !std::isfinite(b.hi[i])) continue;
        l = std::min(l, b.lo[i]), h = std::max(h, b.hi[i]), any = true;
      }
      x.push_back(b.x[i0]);
      lo.push_back(any ? l : NAN);
      hi.push_back(any ? h : NAN);
      x.push_back(b.x[i1 - 1]);
      lo.push_back(any ? l : NAN);
      hi.push_back(any ? h : NAN);
    }
    b.x = std::move(x), b.lo = std::move(lo), b.hi = std::move(hi);
  }
}

std::string renderSvg(const Plot& p) {
  Range xr, yr;
  for (const Series& s : p.series) {
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (std::isfinite(s.x[i]) && std::isfinite(s.y[i])) xr.add(s.x[i]), yr.add(s.y[i]);
    }
  }
  for (const Band& b : p.bands) {
    for (size_t i = 0; i < b.x.size(); ++i) {
      if (!std::isfinite(b.lo[i]) || !std::isfinite(b.hi[i])) continue;
      xr.add(b.x[i]), yr.add(b.lo[i]), yr.add(b.hi[i]);
    }
  }
  for (const ErrorBars& e : p.bars) {
    for (size_t i = 0; i < e.x.size(); ++i) {
      if (!std::isfinite(e.y[i])) continue;
      xr.add(e.x[i]);
      yr.add(e.y[i] - (std::isfinite(e.err[i]) ? e.err[i] : 0.0));
      yr.add(e.y[i] + (std::isfinite(e.err[i]) ? e.err[i] : 0.0));
    }
  }
  const int left = 78, right = 170, top = p.note.empty() ? 30 : 46, bottom = 42;
  const int w = p.width - left - right, h = p.height - top - bottom;
  std::string svg = "<svg class=\"plot\" viewBox=\"0 0 " + std::to_string(p.width) + " " +
                    std::to_string(p.height) + "\" width=\"" + std::to_string(p.width) +
                    "\" height=\"" + std::to_string(p.height) + "\" role=\"img\">";
  svg += "<title>" + htmlEscape(p.title) + "</title>";
  svg += "<text class=\"title\" x=\"" + std::to_string(left) + "\" y=\"18\">" +
         htmlEscape(p.title) + "</text>";
  if (!p.note.empty())
    svg += "<text class=\"note\" x=\"" + std::to_string(left) + "\" y=\"34\">" +
           htmlEscape(p.note) + "</text>";
  if (!xr.valid() || !yr.valid()) {
    svg += "<text class=\"note\" x=\"" + std::to_string(left) + "\" y=\"" +
           std::to_string(top + h / 2) + "\">no data</text></svg>";
    return svg;
  }
  Range x = xr.padded(0.02), y = yr.padded(0.05);
  if (p.equal_aspect) {  // widen the narrower range so metres/pixel agree
    const double sx = (x.hi - x.lo) / w, sy = (y.hi - y.lo) / h;
    if (sx > sy) {
      const double mid = 0.5 * (y.lo + y.hi), half = 0.5 * sx * h;
      y.lo = mid - half, y.hi = mid + half;
    } else {
      const double mid = 0.5 * (x.lo + x.hi), half = 0.5 * sy * w;
      x.lo = mid - half, x.hi = mid + half;
    }
  }
  svg += "<rect class=\"frame\" x=\"" + std::to_string(left) + "\" y=\"" + std::to_string(top) +
         "\" width=\"" + std::to_string(w) + "\" height=\"" + std::to_string(h) + "\"/>";
  svg += "<g class=\"ticks\"></g>";
  svg += "<text class=\"label\" x=\"" + std::to_string(left + w / 2) + "\" y=\"" +
         std::to_string(p.height - 6) + "\" text-anchor=\"middle\">" + htmlEscape(p.x_label) +
         "</text>";
  svg += "<text class=\"label\" transform=\"translate(14 " + std::to_string(top + h / 2) +
         ") rotate(-90)\" text-anchor=\"middle\">" + htmlEscape(p.y_label) + "</text>";
  // The data area: viewBox in data units, y negated.
  svg += "<svg class=\"data\" x=\"" + std::to_string(left) + "\" y=\"" + std::to_string(top) +
         "\" width=\"" + std::to_string(w) + "\" height=\"" + std::to_string(h) +
         "\" preserveAspectRatio=\"none\" viewBox=\"" + num(x.lo) + " " + num(-y.hi) + " " +
         num(x.hi - x.lo) + " " + num(y.hi - y.lo) + "\"" +
         (p.equal_aspect ? " data-equal=\"1\"" : "") + ">";
  const double tall = 1e3 * (y.hi - y.lo);  // spans and lines reach past any pan
  for (const Span& s : p.spans) {
    svg += "<rect class=\"span\" x=\"" + num(s.x0) + "\" y=\"" + num(-y.hi - tall) + "\" width=\"" +
           num(std::max(0.0, s.x1 - s.x0)) + "\" height=\"" + num(2 * tall + y.hi - y.lo) + "\"/>";
  }
  if (!p.vlines.empty()) {
    std::string d;
    for (double v : p.vlines) d += "M" + num(v) + " " + num(-y.hi - tall) + "V" + num(-y.lo + tall);
    svg += "<path class=\"vline\" d=\"" + d + "\"/>";
  }
  for (const Band& b : p.bands) {
    // One polygon per finite stretch.
    std::string d;
    size_t i = 0;
    while (i < b.x.size()) {
      while (i < b.x.size() && !(std::isfinite(b.lo[i]) && std::isfinite(b.hi[i]))) ++i;
      size_t j = i;
      while (j < b.x.size() && std::isfinite(b.lo[j]) && std::isfinite(b.hi[j])) ++j;
      if (j > i) {
        d += "M";
        for (size_t k = i; k < j; ++k) d += num(b.x[k]) + " " + num(-b.hi[k]) + " ";
        for (size_t k = j; k-- > i;) d += num(b.x[k]) + " " + num(-b.lo[k]) + " ";
        d += "Z";
      }
      i = j;
    }
    svg += "<path class=\"band\" fill=\"" + b.color + "\" d=\"" + d + "\"/>";
  }
  for (const Series& s : p.series) {
    if (s.dots) {
      svg += "<path class=\"dots\" stroke=\"" + s.color + "\" stroke-width=\"" + num(s.width) +
             "\" d=\"" + dotData(s.x, s.y) + "\"/>";
    } else {
      svg += "<path class=\"line\" stroke=\"" + s.color + "\" stroke-width=\"" + num(s.width) +
             "\"" + (s.dashed ? " stroke-dasharray=\"5 3\"" : "") + " d=\"" + pathData(s.x, s.y) +
             "\"/>";
    }
  }
  for (const ErrorBars& e : p.bars) {
    std::string bars, dots;
    for (size_t i = 0; i < e.x.size(); ++i) {
      if (!std::isfinite(e.y[i])) continue;
      if (std::isfinite(e.err[i]) && e.err[i] > 0)
        bars +=
            "M" + num(e.x[i]) + " " + num(-(e.y[i] + e.err[i])) + "V" + num(-(e.y[i] - e.err[i]));
      dots += "M" + num(e.x[i]) + " " + num(-e.y[i]) + "h0";
    }
    svg += "<path class=\"line\" stroke=\"" + e.color + "\" stroke-width=\"1.5\" d=\"" + bars +
           "\"/><path class=\"dots\" stroke=\"" + e.color + "\" stroke-width=\"6\" d=\"" + dots +
           "\"/>";
  }
  svg += "</svg>";
  // Legend, right of the data area.
  int ly = top + 10;
  const int lx = left + w + 12;
  auto entry = [&](const std::string& name, const std::string& swatch) {
    svg += "<g transform=\"translate(" + std::to_string(lx) + " " + std::to_string(ly) + ")\">" +
           swatch + "<text class=\"legend\" x=\"26\" y=\"4\">" + htmlEscape(name) + "</text></g>";
    ly += 16;
  };
  for (const Series& s : p.series) {
    if (s.name.empty()) continue;
    entry(s.name,
          s.dots
              ? "<path class=\"dots\" stroke=\"" + s.color + "\" stroke-width=\"6\" d=\"M10 0h0\"/>"
              : "<path class=\"line\" stroke=\"" + s.color + "\" stroke-width=\"" + num(s.width) +
                    "\"" + (s.dashed ? " stroke-dasharray=\"5 3\"" : "") + " d=\"M0 0H20\"/>");
  }
  for (const ErrorBars& e : p.bars) {
    if (e.name.empty()) continue;
    entry(e.name, "<path class=\"line\" stroke=\"" + e.color +
                      "\" stroke-width=\"1.5\" d=\"M10 -6V6\"/><path class=\"dots\" stroke=\"" +
                      e.color + "\" stroke-width=\"6\" d=\"M10 0h0\"/>");
  }
  for (const Band& b : p.bands) {
    if (b.name.empty()) continue;
    entry(b.name, "<rect class=\"band\" fill=\"" + b.color +
                      "\" x=\"0\" y=\"-5\" width=\"20\" "
                      "height=\"10\"/>");
  }
  if (!p.spans.empty())
    entry(p.span_name, "<rect class=\"span\" x=\"0\" y=\"-5\" width=\"20\" height=\"10\"/>");
  if (!p.vlines.empty()) entry(p.vline_name, "<path class=\"vline\" d=\"M10 -6V6\"/>");
  svg += "</svg>";
  return svg;
}

std::string htmlEscape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

const std::string& plotStyle() {
  static const std::string css =
      R"(svg.plot{display:block;margin:6px 0 14px;font:12px sans-serif;background:#fff;user-select:none}
svg.plot .title{font-weight:bold;font-size:13px}
svg.plot .note,svg.plot .label{fill:#444}
svg.plot .frame{fill:none;stroke:#999}
svg.plot svg.data{cursor:crosshair}
svg.plot .line{fill:none;vector-effect:non-scaling-stroke;stroke-linejoin:round}
svg.plot .dots{fill:none;vector-effect:non-scaling-stroke;stroke-linecap:round}
svg.plot .band{opacity:.18;stroke:none}
svg.plot .span{fill:#e8e3c8;opacity:.7}
svg.plot .vline{stroke:#b33;stroke-width:.8;stroke-dasharray:2 3;vector-effect:non-scaling-stroke;fill:none}
svg.plot .grid{stroke:#e6e6e6;stroke-width:1}
svg.plot .tick{fill:#333;font-size:11px}
)";
  return css;
}

const std::string& plotScript() {
  // Written once here; the C++ side writes no ticks. Plain ES5, no library.
  static const std::string js = R"JS((function () {
  var errors = 0;
  window.addEventListener('error', function () {
    errors += 1;
    document.documentElement.setAttribute('data-errors', String(errors));
  });
  document.documentElement.setAttribute('data-errors', '0');
  var NS = 'http://www.w3.org/2000/svg';
  function ticks(lo, hi, n) {
    var span = hi - lo;
    if (!(span > 0)) return [lo];
    var step = Math.pow(10, Math.floor(Math.log(span / n) / Math.LN10));
    var r = span / n / step;
    step *= r >= 7.5 ? 10 : r >= 3.5 ? 5 : r >= 1.5 ? 2 : 1;
    var out = [];
    for (var v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step)
      out.push(Math.abs(v) < step * 1e-9 ? 0 : v);
    return out;
  }
  function label(v) { return String(parseFloat(v.toPrecision(6))); }
  function el(name, attrs, text) {
    var e = document.createElementNS(NS, name);
    for (var k in attrs) e.setAttribute(k, attrs[k]);
    if (text !== undefined) e.textContent = text;
    return e;
  }
  var drawn = 0;
  Array.prototype.forEach.call(document.querySelectorAll('svg.plot'), function (plot) {
    var data = plot.querySelector('svg.data');
    if (!data) return;
    var g = plot.querySelector('g.ticks');
    var px = {x: +data.getAttribute('x'), y: +data.getAttribute('y'),
              w: +data.getAttribute('width'), h: +data.getAttribute('height')};
    var home = data.getAttribute('viewBox');
    var equal = data.getAttribute('data-equal') === '1';
    function view() { return data.getAttribute('viewBox').split(' ').map(Number); }
    function draw() {
      var v = view();
      while (g.firstChild) g.removeChild(g.firstChild);
      ticks(v[0], v[0] + v[2], Math.max(3, px.w / 90)).forEach(function (t) {
        var x = px.x + (t - v[0]) / v[2] * px.w;
        g.appendChild(el('line', {'class': 'grid', x1: x, x2: x, y1: px.y, y2: px.y + px.h}));
        g.appendChild(el('text', {'class': 'tick', x: x, y: px.y + px.h + 14,
                                  'text-anchor': 'middle'}, label(t)));
      });
      ticks(-(v[1] + v[3]), -v[1], Math.max(3, px.h / 45)).forEach(function (t) {
        var y = px.y + (-t - v[1]) / v[3] * px.h;
        g.appendChild(el('line', {'class': 'grid', x1: px.x, x2: px.x + px.w, y1: y, y2: y}));
        g.appendChild(el('text', {'class': 'tick', x: px.x - 5, y: y + 4,
                                  'text-anchor': 'end'}, label(t)));
      });
    }
    data.addEventListener('wheel', function (e) {
      e.preventDefault();
      var v = view(), r = data.getBoundingClientRect();
      var f = e.deltaY > 0 ? 1.25 : 0.8;
      var fx = (e.clientX - r.left) / r.width, fy = (e.clientY - r.top) / r.height;
      if (equal || !e.shiftKey) { var cx = v[0] + fx * v[2]; v[2] *= f; v[0] = cx - fx * v[2]; }
      if (equal || e.shiftKey) { var cy = v[1] + fy * v[3]; v[3] *= f; v[1] = cy - fy * v[3]; }
      data.setAttribute('viewBox', v.join(' '));
      draw();
    }, {passive: false});
    var drag = null;
    data.addEventListener('mousedown', function (e) {
      drag = {x: e.clientX, y: e.clientY, v: view()};
      e.preventDefault();
    });
    window.addEventListener('mousemove', function (e) {
      if (!drag) return;
      var r = data.getBoundingClientRect(), v = drag.v.slice();
      v[0] -= (e.clientX - drag.x) / r.width * v[2];
      v[1] -= (e.clientY - drag.y) / r.height * v[3];
      data.setAttribute('viewBox', v.join(' '));
      draw();
    });
    window.addEventListener('mouseup', function () { drag = null; });
    data.addEventListener('dblclick', function () { data.setAttribute('viewBox', home); draw(); });
    draw();
    drawn += 1;
  });
  document.documentElement.setAttribute('data-plots', String(drawn));
})();
)JS";
  return js;
}

}  // namespace traverse::report
