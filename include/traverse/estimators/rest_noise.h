// The inertial sensors' white noise as the log's rests show it, against what rover.yaml declares.
//
// At rest the gyro reads its bias plus its white noise and the accelerometer gravity plus its
// noise: the spread of each channel about its own mean inside a rest window is that noise. It is
// pooled over every rest window (each window's mean removed, its samples less one as degrees of
// freedom), a margin in from each end so that the detector's delay and a slow start do not count.
// Where the data show a channel noisier than rover.yaml declares — by a factor no sampling scatter
// reaches — every residual and update that assumes the declared σ would be over-confident (a gyro
// 10× noisier than declared gave the EKF a 5.6° yaw RMSE with NEES 13 and had it gate out the sun;
// docs/results.md): the run says so and uses the measured σ. A declared σ larger than the data's
// is kept (conservative, and a rest may hide a quantised or filtered reading).
#pragma once

#include <string>
#include <vector>

#include "traverse/estimators/segmentation.h"
#include "traverse/io/log.h"

namespace traverse::est {

struct RestNoiseOptions {
  /// A rest here is where the wheels stand still (mean |r ψ̇| below this, as the segmentation's
  /// wheel test) for at least min_window_s — not the segmentation's rests, whose detector reads
  /// the gyro against the declared noise: a gyro ten times noisier than declared leaves none.
  double wheel_speed_threshold_mps = 0.002;
  double min_window_s = 2.0;
  double margin_s = 0.5;  ///< left out at each end of a window
  int min_samples = 100;  ///< pooled degrees of freedom needed to judge a channel
  /// measured / declared above this: the declared σ is refuted (s5t1's accelerometer reads
  /// 2.3× its declared σ where its wheels stand still: vibration, not a fault).
  double max_ratio = 3.0;
};

/// One sensor whose rests refute its declared noise.
struct RestNoise {
  std::string file;    ///< "gyro.csv" or "accel.csv"
  std::string column;  ///< the noisiest channel ("wz")
  std::string key;     ///< the rover.yaml key ("gyro.noise_rad_s")
  std::string unit;    ///< "rad/s", "m/s^2"
  double declared = 0.0;
  double measured = 0.0;  ///< the noisiest channel's pooled σ at rest
  int samples = 0;        ///< its pooled degrees of freedom
  int windows = 0;        ///< rest windows that contributed
  double t = 0.0;         ///< the first contributing window's start
  /// "noise at rest 0.0301 rad/s on wz (4310 samples in 12 rests) is 9.7 times
  /// gyro.noise_rad_s 0.0031 in rover.yaml: the measured value is used"
  std::string message() const;
};

/// The gyro and accelerometer channels whose pooled rest noise exceeds max_ratio × declared.
std::vector<RestNoise> restNoise(const io::TraverseLog& log, const RestNoiseOptions& options = {});

/// The log with each refuted noise replaced by its measured value.
io::TraverseLog withRestNoise(const io::TraverseLog& log, const std::vector<RestNoise>& noise);

}  // namespace traverse::est
