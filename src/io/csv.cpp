// CSV stream files (include/traverse/io/csv.h): the contract's headers, a strict single-pass
// parser over the whole file in memory, and a shortest-round-trip writer.
#include "traverse/io/csv.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <stdexcept>

#include "traverse/core/error.h"
#include "traverse/io/input_file.h"
#include "traverse/rover/rover_geometry.h"

namespace traverse::io {
namespace {

using Names = std::vector<std::string>;

std::string join(const Names& names) {
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : ",") + n;
  return out;
}

/// Shortest representation that reads back to the same double.
std::string number(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

/// A field quoted for a message (long garbage shortened).
/// A field quoted for a message (long garbage shortened; control and non-ASCII bytes as \xNN,
/// so the message stays one printable line).
std::string quoted(std::string_view s) {
  constexpr std::size_t kMax = 40;
  std::string out = "'";
  for (const char c : s.substr(0, kMax)) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u < 0x7F) {
      out += c;
    } else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02X", u);
      out += hex;
    }
  }
  return out + (s.size() > kMax ? "…'" : "'");
}

// --- the contract's streams (docs/log-format.md) ---------------------------------------------

/// truth.csv with the contact angles xi1..xiN of an N-wheel rover.
HeaderLayout truthLayout(int wheels) {
  Names xi;
  for (int i = 1; i <= wheels; ++i) xi.push_back("xi" + std::to_string(i));
  return {{"x", "y", "z", "qw", "qx", "qy", "qz"},
          {xi, {"bx", "by", "bz"}, {"vx", "vy", "vz"}, {"wx", "wy", "wz"}}};
}

std::map<std::string, StreamSpec, std::less<>> makeLogSpecs() {
  std::map<std::string, StreamSpec, std::less<>> specs;
  specs["gyro.csv"] = {{{{"wz"}, {}}, {{"wx", "wy", "wz"}, {}}}, {}};
  specs["joints.csv"] = {};  // the columns are the rover's (logStreamSpec with a geometry)
  specs["sun.csv"] = {{{{"s1", "s2", "valid"}, {}}},
                      {{"s1", -1.0, 1.0, false}, {"s2", -1.0, 1.0, false}, {"valid", 0, 1, true}}};
  specs["accel.csv"] = {{{{"ax", "ay", "az"}, {}}}, {}};
  specs["cmd.csv"] = {{{{"vx", "vy", "vz", "wx", "wy", "wz"}, {}}}, {}};
  // Position-only truth: a σ must be positive (a fix with σ = 0 would be an exact constraint).
  constexpr double kInf = std::numeric_limits<double>::infinity();
  specs["gps.csv"] = {
      {{{"x", "y", "z", "sx", "sy", "sz"}, {}}},
      {{"sx", 1e-9, kInf, false}, {"sy", 1e-9, kInf, false}, {"sz", 1e-9, kInf, false}}};
  // Without a geometry the truth's contact angles may be for any number of wheels.
  for (int n = 1; n <= rover::kMaxWheels; ++n) {
    specs["truth.csv"].layouts.push_back(truthLayout(n));
  }
  specs["truth.csv"].unit_norm_groups = {{"qw", "qx", "qy", "qz"}};  // q rotates body → site
  return specs;
}

// --- header ----------------------------------------------------------------------------------

/// Every complete header (with the leading `t`) a spec allows.
std::vector<Names> allowedHeaders(const StreamSpec& spec) {
  std::vector<Names> out;
  for (const HeaderLayout& layout : spec.layouts) {
    const std::size_t groups = layout.optional_groups.size();
    for (unsigned mask = 0; mask < (1U << groups); ++mask) {
      Names h = {"t"};
      h.insert(h.end(), layout.required.begin(), layout.required.end());
      for (std::size_t g = 0; g < groups; ++g) {
        const Names& group = layout.optional_groups[g];
        if ((mask >> g) & 1U) h.insert(h.end(), group.begin(), group.end());
      }
      out.push_back(std::move(h));
    }
  }
  return out;
}

std::string describe(const StreamSpec& spec) {
  if (spec.layouts.empty()) return "a header starting with 't'";
  std::string out;
  for (const HeaderLayout& layout : spec.layouts) {
    if (!out.empty()) out += " or ";
    Names h = {"t"};
    h.insert(h.end(), layout.required.begin(), layout.required.end());
    out += "'" + join(h) + "'";
    if (layout.optional_groups.empty()) continue;
    out += " optionally followed by, in this order,";
    for (const Names& group : layout.optional_groups) out += " '" + join(group) + "'";
  }
  return out;
}

/// Checks a header against the spec; returns the value columns. Throws naming the problem.
Names checkHeader(const Names& header, const StreamSpec& spec, const std::string& file, long line) {
  const auto fail = [&](const std::string& what) { throw InputError(file, line, what); };
  std::set<std::string> seen;
  for (const std::string& c : header) {
    if (c.empty()) fail("empty column name in header (expected " + describe(spec) + ")");
    // A lone '\r' or a tab inside a name: such a header could not be written back, and every
    // message naming the column would print the raw byte.
    if (std::any_of(c.begin(), c.end(), [](char ch) {
          const auto u = static_cast<unsigned char>(ch);
          return u < 0x20 || u == 0x7F;
        })) {
      fail("control character in column name " + quoted(std::string_view(c)));
    }
    if (!seen.insert(c).second) fail("duplicate column '" + c + "' in header");
  }
  const Names values(header.begin() + 1, header.end());
  if (spec.layouts.empty()) {
    if (header.front() != "t") fail("first column must be 't', found '" + header.front() + "'");
    return values;
  }
  const std::vector<Names> allowed = allowedHeaders(spec);
  if (std::find(allowed.begin(), allowed.end(), header) != allowed.end()) return values;
  std::set<std::string> known;
  for (const Names& a : allowed) known.insert(a.begin(), a.end());
  for (const std::string& c : header) {
    if (!known.count(c)) fail("unknown column '" + c + "' (expected " + describe(spec) + ")");
  }
  for (const Names& a : allowed) {
    if (std::set<std::string>(a.begin(), a.end()) == seen) {
      fail("columns in wrong order: expected order '" + join(a) + "', found '" + join(header) +
           "'");
    }
  }
  // Missing columns: name the first one absent from the smallest header holding all given.
  const Names* best = nullptr;
  for (const Names& a : allowed) {
    const std::set<std::string> as(a.begin(), a.end());
    const bool holds = std::includes(as.begin(), as.end(), seen.begin(), seen.end());
    if (holds && (best == nullptr || a.size() < best->size())) best = &a;
  }
  if (best != nullptr) {
    for (const std::string& c : *best) {
      if (!seen.count(c)) fail("missing column '" + c + "' (expected '" + join(*best) + "')");
    }
  }
  fail("header '" + join(header) + "' mixes columns of different layouts (expected " +
       describe(spec) + ")");
  return values;
}

Names splitHeader(std::string_view line) {
  Names out;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    out.emplace_back(line.substr(start, comma - start));
    if (comma == std::string_view::npos) return out;
    start = comma + 1;
  }
}

// --- rows ------------------------------------------------------------------------------------

inline bool parseNumber(const char* b, const char* e, double* v) {
  if (e - b > 1 && *b == '+' && b[1] != '-') ++b;  // C's strtod accepts a leading '+'
  const auto r = std::from_chars(b, e, *v);
  return r.ec == std::errc() && r.ptr == e && b != e;
}

class Parser {
 public:
  Parser(std::string_view text, const std::string& file, const StreamSpec& spec,
         const ReadOptions& options)
      : text_(text), file_(file), spec_(spec), options_(options) {
    if (text_.substr(0, 3) == "\xEF\xBB\xBF") text_.remove_prefix(3);  // UTF-8 byte-order mark
    rejectBinary(text_, file_);  // no row of a binary file is trusted, even with skip_bad_rows
  }

  Stream run(ReadReport* report) {
    readHeader();
    // Capacity: one row per remaining line; exact unless there are comments or bad rows.
    const std::string_view rest = text_.substr(pos_);
    const auto lines =
        std::count(rest.begin(), rest.end(), '\n') + (!rest.empty() && rest.back() != '\n' ? 1 : 0);
    t_.resize(lines);
    values_.resize(lines, static_cast<Eigen::Index>(columns_.size()));
    std::string_view line;
    bool newline = false;
    while (nextLine(&line, &newline)) parseRow(line, newline);
    if (rows_ == 0) {
      throw InputError(
          file_, header_line_,
          skipped_ > 0 ? "no usable data rows (all " + std::to_string(skipped_) + " skipped as bad)"
                       : "header only, no data rows");
    }
    if (report != nullptr && skipped_ > 0) {
      report->skipped_rows[std::filesystem::path(file_).filename().string()] += skipped_;
    }
    return assemble();
  }

 private:
  /// Next line that is neither empty (or blank) nor a comment; false at the end of the text.
  bool nextLine(std::string_view* line, bool* newline) {
    while (pos_ < text_.size()) {
      const char* begin = text_.data() + pos_;
      const auto* nl = static_cast<const char*>(std::memchr(begin, '\n', text_.size() - pos_));
      const std::size_t len = nl ? static_cast<std::size_t>(nl - begin) : text_.size() - pos_;
      pos_ += len + (nl ? 1 : 0);
      ++line_;
      std::string_view l(begin, len);
      if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
      if (l.empty() || l.front() == '#') continue;
      if ((l.front() == ' ' || l.front() == '\t') && l.find_first_not_of(" \t") == l.npos) continue;
      *line = l;
      *newline = nl != nullptr;
      return true;
    }
    return false;
  }

  void readHeader() {
    std::string_view line;
    bool newline = false;
    if (!nextLine(&line, &newline)) {
      throw InputError(file_, line_ + 1,
                       "empty file: no header line (expected " + describe(spec_) + ")");
    }
    header_line_ = line_;
    columns_ = checkHeader(splitHeader(line), spec_, file_, line_);
    row_.resize(columns_.size() + 1);
    for (const ColumnRange& r : spec_.ranges) {
      const auto it = std::find(columns_.begin(), columns_.end(), r.column);
      if (it != columns_.end()) ranges_.push_back({it - columns_.begin() + 1, r});
    }
    for (const Names& group : spec_.unit_norm_groups) {
      std::vector<std::ptrdiff_t> idx;
      for (const std::string& c : group) {
        const auto it = std::find(columns_.begin(), columns_.end(), c);
        if (it != columns_.end()) idx.push_back(it - columns_.begin() + 1);
      }
      if (idx.size() == group.size()) unit_groups_.push_back({std::move(idx), join(group)});
    }
  }

  const std::string& columnName(std::size_t k) const {
    static const std::string kT = "t";
    return k == 0 ? kT : columns_[k - 1];
  }

  void parseRow(std::string_view line, bool newline) {
    const char* p = line.data();
    const char* const end = p + line.size();
    const std::size_t n = row_.size();
    for (std::size_t k = 0; k < n; ++k) {
      const auto* comma = static_cast<const char*>(std::memchr(p, ',', end - p));
      if ((comma == nullptr) != (k + 1 == n)) return fieldCountError(line, newline);
      const char* field_end = comma ? comma : end;
      if (!parseNumber(p, field_end, &row_[k])) {
        return fieldError(line, newline, k, std::string_view(p, field_end - p));
      }
      p = field_end + 1;
    }
    if (checkValues(newline)) {
      t_[rows_] = row_[0];
      for (std::size_t k = 1; k < n; ++k)
        values_(rows_, static_cast<Eigen::Index>(k - 1)) = row_[k];
      ++rows_;
      prev_t_ = row_[0];
    }
  }

  /// NaN/inf, time order and physical ranges of the parsed row_.
  bool checkValues(bool newline) {
    for (std::size_t k = 0; k < row_.size(); ++k) {
      if (std::isfinite(row_[k])) continue;
      return bad(std::string(std::isnan(row_[k]) ? "NaN" : "infinite value " + number(row_[k])) +
                     " in column '" + columnName(k) + "'",
                 newline);
    }
    const double t = row_[0];
    if (rows_ > 0 && !(t > prev_t_)) {
      return bad(
          t == prev_t_
              ? "duplicate time: t=" + number(t) + " equals the previous row's t=" + number(prev_t_)
              : "non-increasing time: t=" + number(t) + " after the previous t=" + number(prev_t_),
          newline);
    }
    for (const auto& [k, r] : ranges_) {
      const double v = row_[k];
      if (r.boolean && v != 0.0 && v != 1.0) {
        return bad("value " + number(v) + " in column '" + r.column + "' must be 0 or 1", newline);
      }
      if (v < r.min || v > r.max) {
        return bad("value " + number(v) + " in column '" + r.column + "' out of physical range [" +
                       number(r.min) + ", " + number(r.max) + "]",
                   newline);
      }
    }
    for (const auto& [idx, name] : unit_groups_) {
      double norm2 = 0.0;
      for (const std::ptrdiff_t k : idx) {
        const double v = row_[static_cast<std::size_t>(k)];
        norm2 += v * v;
      }
      const double norm = std::sqrt(norm2);
      if (std::abs(norm - 1.0) > kUnitNormTolerance) {
        return bad("quaternion (" + name + ") has norm " + number(norm) + ", not 1 (tolerance " +
                       number(kUnitNormTolerance) + ")",
                   newline);
      }
    }
    return true;
  }

  void fieldCountError(std::string_view line, bool newline) {
    const auto found = std::count(line.begin(), line.end(), ',') + 1;
    const std::string counts =
        "expected " + std::to_string(row_.size()) + " fields, found " + std::to_string(found);
    if (!newline && static_cast<std::size_t>(found) < row_.size()) {
      bad("truncated last line (no newline at end of file): " + counts, true);
    } else {
      bad("wrong number of fields: " + counts, newline);
    }
  }

  void fieldError(std::string_view line, bool newline, std::size_t k, std::string_view field) {
    if (static_cast<std::size_t>(std::count(line.begin(), line.end(), ',')) + 1 != row_.size()) {
      return fieldCountError(line, newline);
    }
    const std::string column = " in column '" + columnName(k) + "'";
    if (field.empty()) {
      bad(!newline && k + 1 == row_.size() ? "truncated last line (no newline at end of file): "
                                             "empty value" +
                                                 column
                                           : "empty value" + column,
          true);
      return;
    }
    double v = 0.0;
    const auto r = std::from_chars(field.data(), field.data() + field.size(), v);
    if (r.ec == std::errc::result_out_of_range && r.ptr == field.data() + field.size()) {
      bad("value " + quoted(field) + column + " is beyond the range of a double", newline);
    } else {
      bad("non-numeric value " + quoted(field) + column, newline);
    }
  }

  /// A bad row: throws, or (skip_bad_rows) counts it and returns false.
  bool bad(const std::string& what, bool newline) {
    if (options_.skip_bad_rows) {
      ++skipped_;
      return false;
    }
    throw InputError(file_, line_,
                     newline ? what : what + " (last line has no newline: truncated file?)");
  }

  Stream assemble() {
    Stream s;
    s.columns = std::move(columns_);
    if (rows_ < t_.size()) {  // comments, blank lines or skipped rows: drop the unused capacity
      t_.conservativeResize(rows_);
      values_ = values_.topRows(rows_).eval();
    }
    s.t = std::move(t_);
    s.values = std::move(values_);
    return s;
  }

  std::string_view text_;
  const std::string& file_;
  const StreamSpec& spec_;
  ReadOptions options_;
  std::size_t pos_ = 0;
  long line_ = 0;
  long header_line_ = 0;
  long skipped_ = 0;
  double prev_t_ = 0.0;
  Names columns_;
  std::vector<std::pair<std::ptrdiff_t, ColumnRange>> ranges_;  ///< (row_ index, range)
  std::vector<std::pair<std::vector<std::ptrdiff_t>, std::string>> unit_groups_;  ///< row_ indices
  std::vector<double> row_;  ///< the row being parsed: t, then the values
  Eigen::VectorXd t_;        ///< filled in place: no copy at the end
  Eigen::MatrixXd values_;
  Eigen::Index rows_ = 0;
};

}  // namespace

const StreamSpec& logStreamSpec(std::string_view file_name) {
  static const auto specs = makeLogSpecs();
  const auto it = specs.find(file_name);
  if (it == specs.end())
    throw std::out_of_range("not a log stream file: " + std::string(file_name));
  return it->second;
}

StreamSpec logStreamSpec(std::string_view file_name, const rover::RoverGeometry& geometry) {
  StreamSpec spec = logStreamSpec(file_name);
  if (file_name == "joints.csv") spec.layouts = {{geometry.columnNames(), {}}};
  if (file_name == "truth.csv") spec.layouts = {truthLayout(geometry.numWheels())};
  return spec;
}

Stream parseCsv(std::string_view text, const std::string& file, const StreamSpec& spec,
                const ReadOptions& options, ReadReport* report) {
  return Parser(text, file, spec, options).run(report);
}

Stream readCsv(const std::filesystem::path& file, const StreamSpec& spec,
               const ReadOptions& options, ReadReport* report) {
  return parseCsv(readInputFile(file), file.string(), spec, options, report);
}

// --- writing ---------------------------------------------------------------------------------

namespace {

void checkWritable(const Stream& s) {
  const auto bad = [](const std::string& what) { throw std::invalid_argument("stream: " + what); };
  if (s.values.rows() != s.t.size() ||
      s.values.cols() != static_cast<Eigen::Index>(s.columns.size())) {
    bad("sizes disagree: " + std::to_string(s.t.size()) + " times, values " +
        std::to_string(s.values.rows()) + "×" + std::to_string(s.values.cols()) + ", " +
        std::to_string(s.columns.size()) + " column names");
  }
  std::set<std::string> seen = {"t"};
  for (const std::string& c : s.columns) {
    if (c.empty() || c.find_first_of(",\r\n") != std::string::npos || !seen.insert(c).second) {
      bad("column name '" + c + "' is empty, repeated, 't', or holds ',' or a line break");
    }
  }
  for (Eigen::Index i = 0; i < s.t.size(); ++i) {
    if (!std::isfinite(s.t[i]) || (i > 0 && !(s.t[i] > s.t[i - 1]))) {
      bad("time " + number(s.t[i]) + " at row " + std::to_string(i) +
          " is not finite or not after the previous one");
    }
  }
  if (!s.values.allFinite()) bad("holds a non-finite value (the reader rejects NaN and inf)");
}

/// Appends rows [begin, end) to `out`, shortest round-trip numbers.
void formatRows(const Stream& s, Eigen::Index begin, Eigen::Index end, std::string* out) {
  constexpr std::size_t kMaxNumber = 32;  // to_chars(double) needs at most 24
  const auto cols = s.values.cols();
  std::size_t used = out->size();
  out->resize(used + static_cast<std::size_t>(end - begin) * (static_cast<std::size_t>(cols) + 1) *
                         (kMaxNumber + 1));
  char* p = out->data() + used;
  for (Eigen::Index i = begin; i < end; ++i) {
    p = std::to_chars(p, p + kMaxNumber, s.t[i]).ptr;
    for (Eigen::Index c = 0; c < cols; ++c) {
      *p++ = ',';
      p = std::to_chars(p, p + kMaxNumber, s.values(i, c)).ptr;
    }
    *p++ = '\n';
  }
  out->resize(static_cast<std::size_t>(p - out->data()));
}

std::string header(const Stream& s) {
  Names h = {"t"};
  h.insert(h.end(), s.columns.begin(), s.columns.end());
  return join(h) + "\n";
}

}  // namespace

std::string formatCsv(const Stream& stream) {
  checkWritable(stream);
  std::string out = header(stream);
  formatRows(stream, 0, stream.size(), &out);
  return out;
}

void writeCsv(const std::filesystem::path& file, const Stream& stream) {
  checkWritable(stream);
  const std::filesystem::path tmp = file.string() + ".tmp";
  const auto fail = [&](const std::string& what) {
    const int err = errno;
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw std::runtime_error("cannot write " + file.string() + ": " + what +
                             (err ? std::string(": ") + std::strerror(err) : ""));
  };
  errno = 0;
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(tmp.c_str(), "wb"), &std::fclose);
  if (!f) fail("cannot create " + tmp.string());
  // Blocks of rows keep the buffer small for any stream size.
  constexpr Eigen::Index kBlock = 16384;
  std::string buf = header(stream);
  for (Eigen::Index i = 0; i <= stream.size(); i += kBlock) {
    formatRows(stream, i, std::min(i + kBlock, stream.size()), &buf);
    if (std::fwrite(buf.data(), 1, buf.size(), f.get()) != buf.size()) fail("write failed");
    buf.clear();
  }
  if (std::fclose(f.release()) != 0) fail("close failed");
  std::error_code ec;
  std::filesystem::rename(tmp, file, ec);
  if (ec) fail("cannot rename " + tmp.string() + ": " + ec.message());
}

}  // namespace traverse::io
