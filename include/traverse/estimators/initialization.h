// Initial state shared by every estimator: attitude from the first rest window — roll and pitch
// from gravity (Nickels, rest mode), yaw from the sun direction (the sun sensor and gravity are
// two non-parallel vectors, so the attitude is fully observable at rest) — bias from the rest
// window's mean gyro, position as given (it is not observable from onboard sensors).
#pragma once

#include "traverse/estimators/segmentation.h"

namespace traverse::est {

struct InitOptions {
  Vec3d position_site = Vec3d::Zero();  ///< where the traverse starts (m)
  double yaw_without_sun_rad = 0.0;     ///< used when no sun reading is available at the start
};

struct InitialState {
  double t = 0.0;
  Vec3d p_site = Vec3d::Zero();
  Quatd q_site_body = Quatd::Identity();
  Vec3d bias = Vec3d::Zero();
  /// Body velocity at t: zero when the log starts at rest, else from the wheels (a log may begin
  /// while the rover drives): v_x = mean_i(r_i ψ̇_i + ω_z (y_i + icr_offset_y,i)) at the first
  /// joint sample, as dead reckoning reads it.
  Vec3d v_body = Vec3d::Zero();
  /// 1σ of roll, pitch, yaw (rad) and of the bias (rad/s) behind the values above.
  Vec3d attitude_sigma = Vec3d::Constant(0.1);
  Vec3d bias_sigma = Vec3d::Constant(0.005);
  /// Roll and pitch came from the first rest window's gravity: they are then off by what an
  /// accelerometer bias tilts gravity by (the EKF correlates them with b_a when it carries it).
  bool roll_pitch_from_gravity = false;
  bool yaw_from_sun = false;  ///< the yaw came from a sun reading (the window's mean or the first)
  bool yaw_from_rest_sun = false;  ///< … from the first rest window's mean sun reading
  bool bias_from_rest = false;     ///< the bias came from the first rest window's gyro mean
  /// The rest window the values came from (into Segmentation::rests; −1 when none): an
  /// estimator that starts from them must not count that window's gravity, mean sun heading or
  /// gyro mean again (the EKF skips them there; the smoother's first segment widens its start
  /// attitude prior instead, as it keeps the window's residuals).
  int rest_index = -1;
  /// The σ behind the values above before any reading of the log: roll and pitch 0.1 rad (as
  /// without gravity), yaw 0.1 rad where a sun reading set it (0 without sun: the heading is
  /// then the gauge), grown by the bias σ over the time to a reading after the start.
  Vec3d attitude_prior_sigma = Vec3d::Constant(0.1);
};

InitialState initialState(const io::TraverseLog& log, const Segmentation& seg,
                          const InitOptions& options = {});

/// Yaw (rad) that makes the measured sun reading consistent with roll and pitch: with
/// u = Ry(pitch) Rx(roll) s_body, yaw = atan2(s_site,y, s_site,x) − atan2(u_y, u_x).
double yawFromSun(const Vec2d& s_m, double roll, double pitch, const Mat3d& R_body_sensor,
                  const Vec3d& sun_site);

}  // namespace traverse::est
