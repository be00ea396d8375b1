// The true trajectory of a log (truth.csv, docs/log-format.md) as a function of time, for
// comparing estimator nodes with truth at their own timestamps.
//
// Between samples: position, contact angles, bias, body velocity and body rate are linear;
// attitude is slerp (the constant-rate rotation between the two samples). Outside the truth's
// time span every quantity is clamped to the first or last sample.
#pragma once

#include <array>
#include <vector>

#include <Eigen/Core>

#include "traverse/core/types.h"
#include "traverse/io/log.h"
#include "traverse/rover/rover_geometry.h"

namespace traverse::eval {

class TruthTrajectory {
 public:
  /// From a truth stream (t,x,y,z,qw,qx,qy,qz[,xi1..xi6][,bx,by,bz][,vx,vy,vz][,wx,wy,wz]).
  /// Throws std::invalid_argument if the stream is empty or lacks a pose column.
  explicit TruthTrajectory(const io::Stream& truth);

  Eigen::Index size() const { return static_cast<Eigen::Index>(t_.size()); }
  double tStart() const { return t_.front(); }
  double tEnd() const { return t_.back(); }

  /// Which optional column groups truth.csv had.
  bool hasContactAngles() const { return has_xi_; }
  bool hasBias() const { return has_bias_; }
  bool hasVelocity() const { return has_velocity_; }
  bool hasBodyRate() const { return has_rate_; }

  Vec3d position(double t) const;  ///< p_site, m
  Quatd attitude(double t) const;  ///< q_site_body (body → site)
  /// The methods below throw std::logic_error when their group is absent.
  rover::WheelVectord contactAngles(double t) const;  ///< ξ1…ξN, rad
  Vec3d bias(double t) const;                         ///< gyro bias, rad/s, body axes
  Vec3d velocityBody(double t) const;                 ///< m/s
  Vec3d bodyRate(double t) const;                     ///< rad/s

  /// Velocity in the site frame: R(q) v_body when truth has velocities, otherwise the slope of
  /// the position polyline on the segment holding t (the last segment at the end).
  Vec3d velocitySite(double t) const;

  /// Distance travelled along the truth polyline (3-D) from the first sample to time t.
  double distanceTravelled(double t) const;
  /// Length of the truth polyline between t0 and t1 (≥ 0 for t1 ≥ t0).
  double pathLength(double t0, double t1) const {
    return distanceTravelled(t1) - distanceTravelled(t0);
  }

 private:
  /// Sample i and weight a ∈ [0, 1) of sample i + 1: x(t) = (1 − a) x_i + a x_{i+1}.
  struct Bracket {
    std::size_t i = 0;
    double a = 0.0;
  };
  Bracket locate(double t) const;
  Vec3d lerp3(const std::vector<Vec3d>& x, double t) const;

  std::vector<double> t_;
  std::vector<Vec3d> p_;
  std::vector<Quatd> q_;
  std::vector<rover::WheelVectord> xi_;
  std::vector<Vec3d> bias_, v_, w_;
  std::vector<double> s_;  ///< cumulative polyline length at each sample, m
  bool has_xi_ = false, has_bias_ = false, has_velocity_ = false, has_rate_ = false;
};

}  // namespace traverse::eval
