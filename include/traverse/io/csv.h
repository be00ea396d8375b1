// One CSV stream file of a traverse log (docs/log-format.md): strict reading against the
// contract's headers, and writing that reads back bit for bit.
//
// Reading: the whole file is read at once and parsed with std::from_chars (C locale, no
// quoting); `#` comment lines and empty lines are ignored; a leading `+` on a number is
// accepted. The header must be exactly one of the spec's layouts. Every problem is an
// InputError naming the file (as given), the 1-based line and what is wrong. With
// ReadOptions::skip_bad_rows, row-level problems (non-numeric field, NaN/inf, wrong field count
// or truncated last line, non-increasing or duplicate time, value out of physical range) drop
// the row and count it in ReadReport::skipped_rows[file name]; problems with the file or its
// header (missing, empty, header only, missing/unknown/misordered column) always throw, and so
// do a file larger than maxInputBytes() (refused before it is read, input_file.h) and binary
// content (a NUL byte anywhere). A UTF-8 byte-order mark and CRLF line ends are accepted.
//
// Writing: numbers are formatted with std::to_chars' shortest round-trip representation, so
// writeCsv → readCsv reproduces every double bit for bit (including −0, subnormals and extreme
// exponents). The file is first written to "<file>.tmp" and then renamed over <file>, so a
// failure never leaves a half-written file or destroys the previous one.
#pragma once

#include <filesystem>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "traverse/io/log.h"
#include "traverse/rover/rover_geometry.h"

namespace traverse::io {

/// Physical range of one column; a value outside it is a bad row.
struct ColumnRange {
  std::string column;
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
  bool boolean = false;  ///< the value must be exactly 0 or 1
};

/// One allowed header: `t`, the required columns, then each optional group either complete or
/// absent, the present groups in the given order.
struct HeaderLayout {
  std::vector<std::string> required;
  std::vector<std::vector<std::string>> optional_groups;
};

/// What a stream file may contain. No layouts = any header starting with `t` whose column
/// names are non-empty and unique (estimator outputs).
struct StreamSpec {
  std::vector<HeaderLayout> layouts;  ///< alternatives, e.g. `t,wz` or `t,wx,wy,wz`
  std::vector<ColumnRange> ranges;
  /// Columns that together must have Euclidean norm 1 within kUnitNormTolerance (a quaternion),
  /// when all of them are present; a row that does not is a bad row.
  std::vector<std::vector<std::string>> unit_norm_groups = {};
};

/// |‖q‖ − 1| allowed for a unit group: far above rounding in a double (1e-16) or a float
/// normalised and printed with 7 digits (1e-7), far below any real error.
inline constexpr double kUnitNormTolerance = 1e-6;

/// The contract's spec of a log stream by file name: "gyro.csv", "joints.csv", "sun.csv",
/// "accel.csv", "cmd.csv", "truth.csv" or "gps.csv". Throws std::out_of_range for any other name.
/// Without a rover, joints.csv may have any columns and truth.csv contact angles for any number
/// of wheels.
const StreamSpec& logStreamSpec(std::string_view file_name);
/// The same for one rover: joints.csv carries exactly its coordinates (RoverGeometry::coords,
/// in order), truth.csv its wheels' contact angles xi1..xiN.
StreamSpec logStreamSpec(std::string_view file_name, const rover::RoverGeometry& geometry);

/// Reads one stream file. Errors: InputError(file, line, message).
Stream readCsv(const std::filesystem::path& file, const StreamSpec& spec,
               const ReadOptions& options = {}, ReadReport* report = nullptr);

/// Same, from text in memory; `file` names it in errors and (its file name) in the report.
Stream parseCsv(std::string_view text, const std::string& file, const StreamSpec& spec,
                const ReadOptions& options = {}, ReadReport* report = nullptr);

/// The file text of a stream: header "t,<columns…>" then one line per sample, shortest
/// round-trip numbers. Throws std::invalid_argument if the stream is inconsistent (sizes,
/// empty/duplicate column names or names containing ',' or a line break), holds a non-finite
/// value or its times do not strictly increase — a file the reader would reject.
std::string formatCsv(const Stream& stream);

/// Writes formatCsv(stream) to "<file>.tmp", then renames it to `file`. Throws
/// std::invalid_argument (see formatCsv) or std::runtime_error naming the file on I/O failure.
void writeCsv(const std::filesystem::path& file, const Stream& stream);

}  // namespace traverse::io
