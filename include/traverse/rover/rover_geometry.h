// The rover's kinematic description: a tree of revolute joints from the body to six wheels.
//
// Built from a URDF by io/rover_description.h; nothing here knows about Rocky-7. The joint
// coordinates follow the joints.csv column order of the log contract (log-format.md).
#pragma once

#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "traverse/core/se3.h"

namespace traverse::rover {

inline constexpr int kNumWheels = 6;
inline constexpr int kNumCoords = 11;

/// Generalised joint coordinates, in joints.csv column order.
enum Coord : int {
  kGamma0 = 0,  // rocker differential γ0
  kGamma1,      // left bogie γ1
  kGamma2,      // right bogie γ2
  kLambda1,     // left steering λ1
  kLambda2,     // right steering λ2
  kPsi1,        // wheel drive angles ψ1..ψ6 (1 left front, 2-3 left bogie, 4 right front, 5-6)
  kPsi2,
  kPsi3,
  kPsi4,
  kPsi5,
  kPsi6,
};

inline constexpr std::array<std::string_view, kNumCoords> kCoordNames = {
    "gamma0", "gamma1", "gamma2", "lambda1", "lambda2", "psi1",
    "psi2",   "psi3",   "psi4",   "psi5",    "psi6"};

/// Joint coordinate vector q (radians), in kCoordNames order.
template <typename T>
using JointVector = Eigen::Matrix<T, kNumCoords, 1>;
using JointVectord = JointVector<double>;

/// One joint of the kinematic tree (URDF joint). Its angle is multiplier·q[coord] + offset
/// (the URDF mimic mechanism expresses the rocker differential: right = −left).
struct KinematicJoint {
  std::string name;
  int parent = -1;              ///< index of the parent joint in RoverGeometry::joints; −1 = body
  Posed origin;                 ///< parent joint frame → this joint frame at zero angle
  Vec3d axis = Vec3d::UnitY();  ///< unit rotation axis in this joint's frame; zero if fixed
  int coord = -1;               ///< driving coordinate (Coord); −1 for a fixed joint
  double multiplier = 1.0;
  double offset = 0.0;
};

struct Wheel {
  int drive_joint = -1;  ///< index of the wheel's drive joint; its frame is the wheel frame f_i
  double radius = 0.0;   ///< m
};

/// Geometry of a six-wheel rocker-bogie rover. Wheel frame f_i (the drive joint's frame,
/// without the drive rotation): origin at the wheel centre, x forward, y along the axle
/// (the drive axis), z up at zero joint angles.
struct RoverGeometry {
  std::string name;
  std::vector<KinematicJoint> joints;  ///< topologically ordered: parents before children
  std::array<Wheel, kNumWheels> wheels;
  /// x (body frame, m) of the line holding the instantaneous centre of rotation during
  /// Ackermann turns and turns in place (the unsteered wheels' "axle"); K §2.3.4.
  double turn_centre_x = 0.0;
};

}  // namespace traverse::rover
