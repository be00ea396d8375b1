// Reading a log directory and summarising it (include/traverse/io/log_reader.h).
#include "traverse/io/log_reader.h"

#include <algorithm>
#include <cstdio>
#include <limits>
#include <utility>

#include "traverse/core/error.h"
#include "traverse/io/csv.h"
#include "traverse/io/diagnostics.h"
#include "traverse/io/input_file.h"
#include "traverse/io/rover_config.h"
#include "traverse/io/rover_description.h"

namespace traverse::io {
namespace {

namespace fs = std::filesystem;

void requireFile(const fs::path& file) {
  std::error_code ec;
  if (!fs::exists(file, ec)) throw InputError(file.string(), 0, "required file missing");
}

std::optional<Stream> readOptional(const fs::path& dir, const std::string& name,
                                   const rover::RoverGeometry& geometry, const ReadOptions& options,
                                   ReadReport* report) {
  const fs::path file = dir / name;
  std::error_code ec;
  if (!fs::exists(file, ec)) return std::nullopt;
  return readCsv(file, logStreamSpec(name, geometry), options, report);
}

/// rover.yaml says which gyro axes exist; the file must carry exactly those.
void checkGyroAxes(const fs::path& file, const Stream& gyro, const RoverConfig& config) {
  const bool three = gyro.columns.size() == 3;
  const bool want_three = config.gyro.axes == GyroAxes::kThreeAxis;
  if (three == want_three) return;
  throw InputError(file.string(), 0,
                   std::string("header has ") + (three ? "'t,wx,wy,wz'" : "'t,wz'") +
                       " but rover.yaml gyro.axes is " + (want_three ? "'xyz'" : "'z'"));
}

/// rover.yaml's IMU mounting applied to the readings (f_body = R_body_imu f_imu, each row); the
/// log then holds body-frame readings and its config says so (identity), so that nothing turns
/// them twice — a log written back from it is in the body frame with no imu key.
void applyImuMounting(TraverseLog& log) {
  if (!log.config.imu.mounted()) return;
  const Mat3d& R = log.config.imu.R_body_imu;
  const auto turn = [&](Stream& s, const char* x, const char* y, const char* z) {
    const int cx = s.col(x), cy = s.col(y), cz = s.col(z);
    for (Eigen::Index k = 0; k < s.size(); ++k) {
      const Vec3d f = R * Vec3d(s.values(k, cx), s.values(k, cy), s.values(k, cz));
      s.values(k, cx) = f.x(), s.values(k, cy) = f.y(), s.values(k, cz) = f.z();
    }
  };
  // A heading gyro's mounting is a yaw (rover_config.cpp refuses any other): its wz is the body's.
  if (log.gyro.columns.size() == 3) turn(log.gyro, "wx", "wy", "wz");
  if (log.accel) turn(*log.accel, "ax", "ay", "az");
  log.config.imu = ImuConfig{};
}

std::string fixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

std::string notes(const StreamSummary& s) {
  const auto has = [&](const char* c) {
    return std::find(s.columns.begin(), s.columns.end(), c) != s.columns.end();
  };
  if (s.valid_rows)
    return "valid " + std::to_string(*s.valid_rows) + " of " + std::to_string(s.rows);
  if (s.name == "gyro") return s.columns.size() == 3 ? "3-axis" : "heading only";
  if (s.name == "gps") return "position-only truth";
  if (s.name != "truth") return "";
  std::string out = "pose";
  if (has("xi1")) out += " + contact angles";
  if (has("bx")) out += " + gyro bias";
  if (has("vx")) out += " + body velocity";
  if (has("wx")) out += " + body rate";
  return out;
}

}  // namespace

TraverseLog readLog(const fs::path& dir, const ReadOptions& options, ReadReport* report) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    throw InputError(dir.string(), 0,
                     fs::exists(dir, ec) ? "not a directory" : "log directory not found");
  }
  for (const char* name : {"rover.yaml", "gyro.csv", "joints.csv"}) requireFile(dir / name);
  TraverseLog log;
  log.dir = dir;
  log.config = loadRoverConfig(dir / "rover.yaml", options.rover_overlay);
  const fs::path urdf = dir / log.config.urdf_file;
  requireFile(urdf);
  // Read here (not by loadRoverGeometry) for the size limit and the binary check.
  const std::string urdf_text = readInputFile(urdf);
  rejectBinary(urdf_text, urdf.string());
  log.geometry = parseRoverGeometry(urdf_text, log.config, urdf.string());
  log.gyro = readCsv(dir / "gyro.csv", logStreamSpec("gyro.csv"), options, report);
  checkGyroAxes(dir / "gyro.csv", log.gyro, log.config);
  log.joints =
      readCsv(dir / "joints.csv", logStreamSpec("joints.csv", log.geometry), options, report);
  log.sun = readOptional(dir, "sun.csv", log.geometry, options, report);
  log.accel = readOptional(dir, "accel.csv", log.geometry, options, report);
  log.cmd = readOptional(dir, "cmd.csv", log.geometry, options, report);
  log.truth = readOptional(dir, "truth.csv", log.geometry, options, report);
  log.gps = readOptional(dir, "gps.csv", log.geometry, options, report);
  applyImuMounting(log);
  return log;
}

StreamSummary summarizeStream(const std::string& name, const Stream& stream) {
  StreamSummary s;
  s.name = name;
  s.file = name + ".csv";
  s.rows = static_cast<long>(stream.size());
  s.columns = stream.columns;
  if (name == "sun" && stream.has("valid"))
    s.valid_rows = (stream.channel("valid").array() == 1.0).count();
  if (stream.empty()) return s;
  s.t_first = stream.t[0];
  s.t_last = stream.t[stream.size() - 1];
  if (stream.size() < 2) return s;
  s.median_rate_hz = 1.0 / medianInterval(stream);
  // The same gaps as the diagnostics' (io/diagnostics.h): > 3 median intervals.
  for (const Gap& g : findGaps(stream, 3.0)) {
    ++s.gaps;
    s.largest_gap_s = std::max(s.largest_gap_s, g.length_s);
  }
  return s;
}

LogSummary summarize(const TraverseLog& log) {
  LogSummary out;
  out.dir = log.dir.string();
  out.rover_name = log.config.name;
  out.format = log.config.format;
  double t0 = std::numeric_limits<double>::infinity();
  double t1 = -t0;
  for (const auto& [file, stream] : logStreams(log)) {
    if (stream == nullptr) continue;
    const std::string name = std::string(file).substr(0, std::string(file).size() - 4);  // no .csv
    out.streams.push_back(summarizeStream(name, *stream));
    if (stream->empty()) continue;
    t0 = std::min(t0, out.streams.back().t_first);
    t1 = std::max(t1, out.streams.back().t_last);
  }
  if (t0 <= t1) {
    out.t_start = t0;
    out.t_end = t1;
    out.duration_s = t1 - t0;
  }
  return out;
}

std::string formatSummary(const LogSummary& summary) {
  std::string out = "log       " + summary.dir + "\n";
  out += "rover     " + summary.rover_name + " (format " + std::to_string(summary.format) + ")\n";
  out += "duration  " + fixed(summary.duration_s, 3) + " s (t " + fixed(summary.t_start, 3) +
         " to " + fixed(summary.t_end, 3) + " s)\n\n";
  char line[256];
  std::snprintf(line, sizeof line, "%-7s %9s %5s %14s %14s %9s %6s %15s  %s\n", "stream", "rows",
                "cols", "t first (s)", "t last (s)", "rate (Hz)", "gaps", "largest gap (s)",
                "notes");
  out += line;
  for (const StreamSummary& s : summary.streams) {
    const std::string gap = s.gaps > 0 ? fixed(s.largest_gap_s, 3) : "-";
    std::snprintf(line, sizeof line, "%-7s %9ld %5zu %14.3f %14.3f %9.2f %6ld %15s  %s\n",
                  s.name.c_str(), s.rows, s.columns.size(), s.t_first, s.t_last, s.median_rate_hz,
                  s.gaps, gap.c_str(), notes(s).c_str());
    std::string row = line;
    row.erase(row.find_last_not_of(" \n") + 1);  // no trailing blanks when there is no note
    out += row + "\n";
  }
  return out;
}

}  // namespace traverse::io
