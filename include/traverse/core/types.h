// Scalar-templated fixed-size types used throughout traverse.
//
// Quaternions are Eigen::Quaternion (Hamilton convention). Eigen stores the coefficients as
// (x, y, z, w) in memory; wherever a raw array is used this project says so explicitly.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace traverse {

template <typename T>
using Vec2 = Eigen::Matrix<T, 2, 1>;
template <typename T>
using Vec3 = Eigen::Matrix<T, 3, 1>;
template <typename T>
using Vec4 = Eigen::Matrix<T, 4, 1>;
template <typename T>
using Vec6 = Eigen::Matrix<T, 6, 1>;
template <typename T>
using Mat3 = Eigen::Matrix<T, 3, 3>;
template <typename T>
using Mat6 = Eigen::Matrix<T, 6, 6>;
template <typename T>
using Quat = Eigen::Quaternion<T>;

using Vec2d = Vec2<double>;
using Vec3d = Vec3<double>;
using Vec4d = Vec4<double>;
using Vec6d = Vec6<double>;
using Mat3d = Mat3<double>;
using Mat6d = Mat6<double>;
using Quatd = Quat<double>;

/// A twist [v; ω]: linear velocity of the point at the frame origin, then angular velocity
/// (Murray, Li & Sastry convention, as in K-17/K-18).
template <typename T>
using Twist = Vec6<T>;
using Twistd = Twist<double>;

}  // namespace traverse
