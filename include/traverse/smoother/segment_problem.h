// One smoother segment as a Ceres problem: what it reads (SmootherData, shared by all segments
// of a log), which nodes it spans (SegmentSpec) and what it returns (SegmentSolution).
// smoother.h runs these for every segment and stitches them; benchmarks and tests call
// solveSegment directly.
#pragma once

#include <optional>

#include "traverse/io/diagnostics.h"
#include "traverse/sensors/gyro.h"
#include "traverse/smoother/smoother.h"

namespace traverse::smoother {

/// Cumulative trapezoid integral of a piecewise-linear signal: integral(a, b) = ∫_a^b y dt
/// (held constant outside the samples).
class IntegratedSignal {
 public:
  IntegratedSignal() = default;
  IntegratedSignal(const Eigen::VectorXd& t, const Eigen::MatrixXd& values);
  Eigen::VectorXd integral(double a, double b) const { return at(b) - at(a); }
  bool empty() const { return t_.size() == 0; }

 private:
  Eigen::VectorXd at(double t) const;
  Eigen::VectorXd t_;
  Eigen::MatrixXd y_, c_;  ///< samples and cumulative integral (rows: samples)
};

/// Everything the segment problems read, computed once per log.
struct SmootherData {
  SmootherData(const io::TraverseLog& log, const est::Trajectory& seed,
               const SmootherOptions& options);
  const io::TraverseLog& log;
  const est::Trajectory& seed;                   ///< one node per est::jointSamples entry
  std::vector<rover::JointSample> joints;        ///< est::jointSamples(log)
  std::vector<size_t> nodes;                     ///< joint-sample indices that are smoother nodes
  Eigen::Matrix<double, Eigen::Dynamic, 6> cmd;  ///< commanded (v, ω) per node (zero without)
  sensors::GyroAxes gyro_axes = sensors::GyroAxes::headingOnly();  ///< B_g of the log's gyro
  bool has_cmd = false, accel_driven = false;
  double gyro_period_s = 0.05, accel_period_s = 0.1;
  IntegratedSignal gyro, accel;  ///< gyro as 3 axes (heading-only: z)
  /// Where gyro.csv and accel.csv say nothing (io::TimeGaps): a node interval that meets a gyro
  /// gap has no gyro increment (the attitude follows the rate process and the slip rows there),
  /// one that meets an accelerometer gap the velocity random walk instead of O-4.
  io::TimeGaps gyro_gaps, accel_gaps;
};

/// A segment: nodes [first, last] of SmootherData::nodes and the rest windows inside it.
struct SegmentSpec {
  size_t first = 0, last = 0;
  std::vector<const est::RestWindow*> rests;
};

struct SegmentSolution {
  std::vector<est::TrajectoryNode> nodes;  ///< with covariance when has_covariance
  bool has_covariance = false;
  Vec3d bias = Vec3d::Zero(), bias_sigma = Vec3d::Zero();  ///< at the segment's middle
  SegmentSummary summary;  ///< status, iterations, costs, times, sizes
};

SegmentSolution solveSegment(const SmootherData& data, const SegmentSpec& spec,
                             const SmootherOptions& options);

}  // namespace traverse::smoother
