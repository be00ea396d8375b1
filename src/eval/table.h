// Private helpers shared by the metrics and Monte Carlo reports: key order and plain-text
// tables.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace traverse::eval::detail {

/// Position of a key in kMetricKeys; kMetricKeys.size() for any other key.
std::size_t metricKeyRank(std::string_view key);

/// Stable sort into kMetricKeys order; keys outside it keep their relative order at the end.
void sortMetricKeys(std::vector<std::string>& keys);

/// Adds `key` to `keys` unless it is there already.
void addUnique(std::vector<std::string>& keys, const std::string& key);

/// Aligned columns: the first row is the header, the first column left-aligned, the others
/// right-aligned, two spaces apart; widths count UTF-8 code points. Newline-ended lines.
std::string renderTable(const std::vector<std::vector<std::string>>& rows);

/// printf "%.4g" of a value (non-finite ones as printf writes them: "nan", "inf").
std::string formatValue(double value);

}  // namespace traverse::eval::detail
