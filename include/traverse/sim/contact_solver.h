// Contact configuration on a terrain (K §4: the simulator "solves for the contact configuration
// for a set of closely spaced points along a specified rover path").
//
// Given the body's horizontal position, heading and steering angles, find the body height,
// roll, pitch and the suspension angles (rocker-bogie: γ0, γ1, γ2) such that every wheel (a thin
// disc of radius r in its wheel frame's x-z plane) touches the terrain: the lowest point of its
// rim relative to the surface is on the surface, and there the rim is tangent to it. Each
// wheel's contact angle ξ_i is where that happens (rover/kinematics.h convention). A rover with
// as many unknowns (3 + suspension angles) as wheels is solved exactly (Newton); one with more
// wheels than that — a rigid four-wheel rover — in the least-squares sense (Gauss–Newton): on
// uneven ground such a rover stands on three wheels, so its gaps are only as small as the
// terrain allows.
#pragma once

#include <stdexcept>
#include <vector>

#include "traverse/rover/kinematics.h"
#include "traverse/sim/terrain.h"

namespace traverse::sim {

struct ContactState {
  double z = 0.0, roll = 0.0, pitch = 0.0;  ///< body origin height (site), Z-Y-X angles (rad)
  rover::JointVectord suspension;           ///< suspension angles, in RoverGeometry::coords order
  rover::WheelVectord xi;                   ///< contact angles (rad), one per wheel
};

struct ContactSolverOptions {
  double tolerance_m = 1e-9;  ///< |gap| of every wheel at convergence
  int max_iterations = 40;
  double max_joint_angle_rad = 1.2;  ///< beyond this the suspension has no physical solution
  int rim_scan_points = 61;          ///< global check of each wheel's lowest rim point
};

/// Where a wheel touches: the gap between rim and terrain along the vertical, and the angle
/// between the rim's tangent and the surface's tangent plane, at the contact; and the smallest
/// gap anywhere on the rim's lower half (negative = the wheel is below the surface).
struct WheelContactCheck {
  double gap_m = 0.0;
  double tangency_rad = 0.0;
  double min_rim_gap_m = 0.0;
};

class ContactError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class ContactSolver {
 public:
  ContactSolver(const rover::RoverGeometry& geometry, const Terrain& terrain,
                ContactSolverOptions options = {});

  /// Solves at (x, y, yaw) with the given steering angles, starting from `guess` (use
  /// initialGuess() for the first point of a path). Throws ContactError naming the pose.
  /// `steering`: the steering angles, in RoverGeometry::coords order.
  ContactState solve(double x, double y, double yaw, const rover::JointVectord& steering,
                     const ContactState& guess) const;

  /// A starting point from the terrain under the body: level with the local surface normal.
  ContactState initialGuess(double x, double y, double yaw) const;

  /// Checks a solved state (for tests and for the simulator's own assertions).
  std::vector<WheelContactCheck> check(double x, double y, double yaw,
                                       const rover::JointVectord& steering,
                                       const ContactState& state) const;

  /// Height of the body origin above flat ground at zero joint angles (m).
  double bodyHeightAboveGround() const { return centre_height_; }

  /// Site pose of the body for a state.
  static Posed bodyPose(double x, double y, double yaw, const ContactState& s);

 private:
  struct Rim {
    Vec3d centre, x_axis, z_axis;
    double radius;
  };
  std::vector<Rim> rims(const Posed& T_site_body, const rover::JointVectord& q) const;
  double gap(const Rim& rim, double xi) const;
  /// gap at an angle given by its sine and cosine (the scan's fixed angles, tabulated once).
  double gap(const Rim& rim, double sin_xi, double cos_xi) const;
  double gapSlope(const Rim& rim, double xi) const;
  double lowestRimPoint(const Rim& rim, double xi_start) const;
  rover::JointVectord joints(const rover::JointVectord& suspension,
                             const rover::JointVectord& steering) const;

  const rover::RoverGeometry& geometry_;
  std::vector<int> suspension_, steering_;  ///< their coordinates
  const Terrain& terrain_;
  ContactSolverOptions options_;
  double centre_height_ = 0.0;  ///< wheel-centre z below the body at zero joint angles (mean)
  std::vector<double> scan_xi_, scan_sin_, scan_cos_;  ///< lowestRimPoint's scan angles
};

}  // namespace traverse::sim
