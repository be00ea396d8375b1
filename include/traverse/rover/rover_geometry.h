// The rover's kinematic description: a tree of revolute joints from the body to its wheels.
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

/// Capacity of the fixed-storage vectors below (no heap allocation on the hot paths): a rover
/// may have up to kMaxWheels wheels and kMaxCoords joint coordinates (joints.csv columns).
inline constexpr int kMaxWheels = 12;
inline constexpr int kMaxCoords = 40;

/// What a joint coordinate is (io/rover_description.cpp classifies them from the URDF): the
/// drive angle ψ of a wheel, a steering angle λ (a joint whose axis is near the body's vertical
/// at zero angles), or a suspension angle γ (every other movable joint).
enum class CoordKind { kSuspension, kSteering, kDrive };

/// One joint coordinate: a joints.csv column (log-format.md) driving one URDF joint (and the
/// joints that mimic it).
struct Coordinate {
  std::string column;  ///< joints.csv column name
  std::string joint;   ///< URDF joint name
  CoordKind kind = CoordKind::kSuspension;
  int wheel = -1;  ///< index of the wheel it drives (kDrive), else −1
};

/// Generalised joint coordinates q (radians), in RoverGeometry::coords order (the joints.csv
/// column order). Fixed storage of kMaxCoords, size numCoords().
template <typename T>
using JointVector = Eigen::Matrix<T, Eigen::Dynamic, 1, 0, kMaxCoords, 1>;
using JointVectord = JointVector<double>;
/// One value per wheel (contact angles), fixed storage of kMaxWheels, size numWheels().
template <typename T>
using WheelVector = Eigen::Matrix<T, Eigen::Dynamic, 1, 0, kMaxWheels, 1>;
using WheelVectord = WheelVector<double>;

/// One joint of the kinematic tree (URDF joint). Its angle is multiplier·q[coord] + offset
/// (the URDF mimic mechanism expresses the rocker differential: right = −left).
struct KinematicJoint {
  std::string name;
  int parent = -1;              ///< index of the parent joint in RoverGeometry::joints; −1 = body
  Posed origin;                 ///< parent joint frame → this joint frame at zero angle
  Vec3d axis = Vec3d::UnitY();  ///< unit rotation axis in this joint's frame; zero if fixed
  int coord = -1;               ///< driving coordinate (index into coords); −1 for a fixed joint
  double multiplier = 1.0;
  double offset = 0.0;
};

struct Wheel {
  int drive_joint = -1;  ///< index of the wheel's drive joint; its frame is the wheel frame f_i
  int coord = -1;        ///< index of its drive angle ψ_i in RoverGeometry::coords
  double radius = 0.0;   ///< m
  bool steered = false;  ///< a steering joint is on its chain
  /// y_ICR − y of the wheel (m, body, at zero joint angles): its nominal longitudinal slip is
  /// ω_z times it (skid steering, io::SkidSteerConfig; 0 for a wheel that just rolls).
  double icr_offset_y = 0.0;
  /// How the ICR's half-track error δ moves it (io::SkidSteerConfig): y_ICR = … + icr_side · δ,
  /// +1 for a left wheel, −1 for a right one, 0 without skid steering.
  double icr_side = 0.0;
  /// Which side's radius scale the wheel takes (io::OdometryConfig): 1 left (body y > 0 at
  /// zero joint angles), 0 right (y < 0), ½ on the centre line.
  double left_share = 0.5;
};

/// Geometry of a wheeled rover (any number of wheels; suspension and steering joints optional,
/// a rover without them is rigid). Wheel frame f_i (the drive joint's frame,
/// without the drive rotation): origin at the wheel centre, x forward, y along the axle
/// (the drive axis), z up at zero joint angles.
struct RoverGeometry {
  std::string name;
  std::vector<KinematicJoint> joints;  ///< topologically ordered: parents before children
  std::vector<Coordinate> coords;      ///< joint coordinates in joints.csv column order
  std::vector<Wheel> wheels;           ///< in the order of their drive angles in `coords`
  /// x (body frame, m) of the line holding the instantaneous centre of rotation during
  /// Ackermann turns and turns in place (the unsteered wheels' "axle"); K §2.3.4.
  double turn_centre_x = 0.0;

  int numWheels() const { return static_cast<int>(wheels.size()); }
  int numCoords() const { return static_cast<int>(coords.size()); }
  /// Indices into `coords` of the coordinates of one kind, in column order.
  std::vector<int> coordsOfKind(CoordKind kind) const {
    std::vector<int> out;
    for (int c = 0; c < numCoords(); ++c)
      if (coords[static_cast<size_t>(c)].kind == kind) out.push_back(c);
    return out;
  }
  /// Zero joint coordinates of this rover.
  JointVectord zeroJoints() const { return JointVectord::Zero(numCoords()); }
  /// joints.csv value columns (without `t`).
  std::vector<std::string> columnNames() const {
    std::vector<std::string> out;
    for (const Coordinate& c : coords) out.push_back(c.column);
    return out;
  }
};

}  // namespace traverse::rover
