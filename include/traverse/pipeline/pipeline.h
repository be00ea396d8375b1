// The estimation pipeline on one log (the layer above estimators and smoother): segmentation →
// initial state → dead reckoning and the forward EKF → the per-segment batch smoother (when asked),
// and the rows of segments.csv.
#pragma once

#include <optional>
#include <vector>

#include "traverse/estimators/dead_reckoning.h"
#include "traverse/estimators/ekf.h"
#include "traverse/estimators/segments_output.h"
#include "traverse/smoother/smoother.h"

namespace traverse::pipeline {

using est::DeadReckoningOptions;
using est::EkfOptions;
using est::EkfResult;
using est::InitialState;
using est::InitOptions;
using est::Segmentation;
using est::SegmentationOptions;
using est::SegmentRow;
using est::Trajectory;

struct PipelineConfig {
  SegmentationOptions segmentation;
  InitOptions init;
  DeadReckoningOptions dead_reckoning;
  EkfOptions ekf;
  bool smooth = false;  ///< run the smoother after the EKF
  smoother::SmootherOptions smoother;
};

struct Estimates {
  Segmentation segmentation;
  InitialState init;
  Trajectory dr;
  EkfResult ekf;
  std::optional<smoother::SmootherResult> smoothed;
  std::vector<SegmentRow> segments;  ///< the smoother's bias and summary on motion rows
};

Estimates estimate(const io::TraverseLog& log, const PipelineConfig& config = {});

/// segments.csv rows from the segmentation and a trajectory with bias estimates: a rest row
/// carries the window's own bias measurement on the gyro's axes (mean ± standard error), a
/// motion row the trajectory's bias at the segment's end.
std::vector<SegmentRow> segmentRows(const Segmentation& seg, const Trajectory& trajectory);

}  // namespace traverse::pipeline
