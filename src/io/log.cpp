// The small members of the in-memory log (include/traverse/io/log.h).
#include "traverse/io/log.h"

#include <algorithm>
#include <numeric>
#include <stdexcept>
#include <vector>

namespace traverse::io {

int Stream::col(std::string_view name) const {
  for (std::size_t i = 0; i < columns.size(); ++i) {
    if (columns[i] == name) return static_cast<int>(i);
  }
  return -1;
}

Eigen::Ref<const Eigen::VectorXd> Stream::channel(std::string_view name) const {
  const int c = col(name);
  if (c < 0) throw std::out_of_range("stream has no column '" + std::string(name) + "'");
  // A column of a column-major matrix is contiguous: the Ref views it, no copy.
  return values.col(c);
}

double medianPeriod(const Stream& s) {
  if (s.size() < 2) return 0.1;
  std::vector<double> d(static_cast<size_t>(s.size() - 1));
  for (Eigen::Index k = 1; k < s.size(); ++k) d[static_cast<size_t>(k - 1)] = s.t[k] - s.t[k - 1];
  std::nth_element(d.begin(), d.begin() + static_cast<long>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

Eigen::VectorXd interpolateRow(const Stream& s, double t) {
  const double* b = s.t.data();
  const double* e = b + s.size();
  const double* it = std::lower_bound(b, e, t);
  if (it == b) return s.values.row(0).transpose();
  if (it == e) return s.values.row(s.size() - 1).transpose();
  const Eigen::Index k = it - b;
  const double u = (t - s.t[k - 1]) / (s.t[k] - s.t[k - 1]);
  return ((1 - u) * s.values.row(k - 1) + u * s.values.row(k)).transpose();
}

long ReadReport::totalSkipped() const {
  return std::accumulate(skipped_rows.begin(), skipped_rows.end(), 0L,
                         [](long sum, const auto& kv) { return sum + kv.second; });
}

}  // namespace traverse::io
