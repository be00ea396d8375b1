// A traverse log in memory (the contract: docs/log-format.md, ../shared/docs/log-format.md).
//
// Streams are column-wise: `t` is one vector, `values` an N×C Eigen matrix (column-major, so
// each channel is contiguous). Every stream keeps its own timestamps.
#pragma once

#include <array>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "traverse/io/rover_config.h"
#include "traverse/rover/rover_geometry.h"

namespace traverse::io {

struct Stream {
  std::vector<std::string> columns;  ///< value columns, without the leading `t`
  Eigen::VectorXd t;                 ///< seconds, strictly increasing
  Eigen::MatrixXd values;            ///< rows = samples, cols = columns

  Eigen::Index size() const { return t.size(); }
  bool empty() const { return t.size() == 0; }
  /// Index of a value column, or −1.
  int col(std::string_view name) const;
  bool has(std::string_view name) const { return col(name) >= 0; }
  /// One channel by name (throws std::out_of_range if absent).
  Eigen::Ref<const Eigen::VectorXd> channel(std::string_view name) const;
};

/// Median sample period of a stream (s); 0.1 with fewer than two samples.
double medianPeriod(const Stream& s);
/// A stream's row linearly interpolated at time t (clamped to the first and last rows).
Eigen::VectorXd interpolateRow(const Stream& s, double t);

struct TraverseLog {
  std::filesystem::path dir;
  RoverConfig config;
  rover::RoverGeometry geometry;
  Stream gyro;                  ///< t,wz  or  t,wx,wy,wz
  Stream joints;                ///< t,gamma0,…,psi6
  std::optional<Stream> sun;    ///< t,s1,s2,valid
  std::optional<Stream> accel;  ///< t,ax,ay,az
  std::optional<Stream> cmd;    ///< t,vx,vy,vz,wx,wy,wz
  std::optional<Stream> truth;  ///< t,x,y,z,qw,qx,qy,qz[,xi1..xi6][,bx,by,bz][,vx,vy,vz][,wx,wy,wz]
  /// Position-only truth: t,x,y,z,sx,sy,sz — the GPS antenna in the site frame and its 1σ per
  /// axis (m); the antenna's lever arm is RoverConfig::gps.
  std::optional<Stream> gps;
  /// Stretches in which one wheel's drive angle is not to be used (the reader leaves this
  /// empty; the pipeline's screen fills it from a `stuck` finding): its slip rows and its share
  /// of dead reckoning's wheel average are left out there.
  struct WheelOutage {
    int wheel = 0;  ///< index into geometry.wheels
    double t_start = 0.0, t_end = 0.0;
  };
  std::vector<WheelOutage> wheel_outages;
  /// Whether wheel `wheel`'s drive angle may be used at t, `margin` seconds clear of every
  /// outage (a rate differenced from neighbouring samples carries the outage that far).
  bool wheelUsed(int wheel, double t, double margin = 0.0) const {
    for (const WheelOutage& o : wheel_outages) {
      if (o.wheel == wheel && t >= o.t_start - margin && t <= o.t_end + margin) return false;
    }
    return true;
  }
};

/// Every stream of a log with its file name, in the contract's order (gyro, joints, sun, accel,
/// cmd, truth, gps); nullptr for an absent optional stream. Readers, writers and diagnostics walk
/// this one list.
struct NamedStream {
  const char* file;  ///< "gyro.csv", …
  const Stream* stream;
};
inline std::array<NamedStream, 7> logStreams(const TraverseLog& log) {
  const auto opt = [](const std::optional<Stream>& s) { return s ? &*s : nullptr; };
  return {{{"gyro.csv", &log.gyro},
           {"joints.csv", &log.joints},
           {"sun.csv", opt(log.sun)},
           {"accel.csv", opt(log.accel)},
           {"cmd.csv", opt(log.cmd)},
           {"truth.csv", opt(log.truth)},
           {"gps.csv", opt(log.gps)}}};
}

/// Whether sun.csv exists and holds a valid reading (valid = 1): without one nothing measures
/// the heading, and the start's is the site frame's gauge (docs/model.md "Initial state").
inline bool hasValidSunReading(const std::optional<Stream>& sun) {
  if (!sun || !sun->has("valid")) return false;
  return (sun->channel("valid").array() > 0.5).any();
}

struct ReadOptions {
  bool skip_bad_rows = false;  ///< count and drop malformed rows instead of stopping
  /// A rover.yaml overlay applied over the log's own (io::loadRoverConfig; empty: none), e.g.
  /// the odometry calibration `traverse calibrate` writes.
  std::filesystem::path rover_overlay;
};

/// What a read skipped (per file name), when ReadOptions::skip_bad_rows is set.
struct ReadReport {
  std::map<std::string, long> skipped_rows;
  long totalSkipped() const;
};

}  // namespace traverse::io
