// Shared test helper: the bundled Rocky-7 geometry (datasets/rovers/rocky7), loaded once.
#pragma once

#include <string>

#include "support/jacobian_check.h"
#include "traverse/io/rover_description.h"

namespace traverse::testing {

inline const rover::RoverGeometry& rocky7() {
  static const rover::RoverGeometry geo = [] {
    const std::string dir = sourceDir() + "/datasets/rovers/rocky7/";
    return io::loadRoverGeometry(dir + "rover.urdf", io::loadRoverConfig(dir + "rover.yaml"));
  }();
  return geo;
}

}  // namespace traverse::testing
