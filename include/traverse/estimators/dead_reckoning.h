// Dead reckoning, the baseline (R §4.3, K §4.1.1): averaged wheel odometry — the mean of the six
// wheels' rolling speeds r_i ψ̇_i — integrated along the gyro heading at the turn-centre point
// (the one point an Ackermann turn moves along the heading; the body origin follows rigidly),
// the gyro corrected by the bias of the latest rest window. Roll and pitch are held from the latest
// rest window's gravity measurement; with `pitch_projection` the wheel speed is projected by the
// pitch before integration (K §4.1.1 mentions it; the paper found it negligible on its terrain).
#pragma once

#include "traverse/estimators/initialization.h"
#include "traverse/estimators/trajectory.h"

namespace traverse::est {

struct DeadReckoningOptions {
  bool pitch_projection = false;
};

/// One node per joint sample.
Trajectory deadReckoning(const io::TraverseLog& log, const Segmentation& seg,
                         const InitialState& init, const DeadReckoningOptions& options = {});

}  // namespace traverse::est
