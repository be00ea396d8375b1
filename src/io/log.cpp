// The small members of the in-memory log (include/traverse/io/log.h).
#include "traverse/io/log.h"

#include <numeric>
#include <stdexcept>

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

long ReadReport::totalSkipped() const {
  return std::accumulate(skipped_rows.begin(), skipped_rows.end(), 0L,
                         [](long sum, const auto& kv) { return sum + kv.second; });
}

}  // namespace traverse::io
