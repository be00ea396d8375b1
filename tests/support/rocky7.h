// Shared test helpers: the bundled Rocky-7 geometry (datasets/rovers/rocky7), loaded once, and
// joint samples of it at random joint angles and rates.
#pragma once

#include <random>
#include <string>

#include "support/jacobian_check.h"
#include "support/rocky7_coords.h"
#include "traverse/io/rover_description.h"
#include "traverse/rover/joint_sample.h"
#include "traverse/rover/slip_constraint.h"

namespace traverse::testing {

inline const rover::RoverGeometry& rocky7() {
  static const rover::RoverGeometry geo = [] {
    const std::string dir = sourceDir() + "/datasets/rovers/rocky7/";
    return io::loadRoverGeometry(dir + "rover.urdf", io::loadRoverConfig(dir + "rover.yaml"));
  }();
  return geo;
}

/// A joint sample at random suspension and steering angles (±0.3 rad) and random joint rates
/// (±0.5 rad/s): wheel frames and joint twists only (no covariances).
inline rover::JointSample randomJointSample(std::mt19937& rng) {
  const rover::RoverGeometry& geo = rocky7();
  const rover::JointVectord q = randomVector<r7::kNumCoords>(rng, 0.3);
  const rover::JointVectord q_dot = randomVector<r7::kNumCoords>(rng, 0.5);
  const auto kin = rover::forwardKinematics<double>(geo, q);
  rover::JointSample js;
  js.resize(geo.numWheels());
  for (int i = 0; i < r7::kNumWheels; ++i) {
    js.T_body_wheel[i] = kin[i].T_body_wheel;
    js.joint_twist[i] = rover::wheelJointTwist(kin[i], q_dot);
  }
  return js;
}

}  // namespace traverse::testing
