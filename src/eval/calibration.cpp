#include "traverse/eval/calibration.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <sstream>
#include <stdexcept>

#include <ceres/ceres.h>

#include "traverse/core/error.h"
#include "traverse/core/so3.h"
#include "traverse/eval/position_truth.h"
#include "traverse/eval/truth.h"
#include "traverse/rover/joint_rates.h"
#include "traverse/rover/kinematics.h"

namespace traverse::eval {
namespace {

using Vec2 = Eigen::Vector2d;
using Coef2 = Eigen::Matrix<double, 2, 4>;

/// A quantity linear in the parameters θ = (s_L, s_R, y_ICR,L, y_ICR,R): c θ + e.
struct Linear2 {
  Coef2 c = Coef2::Zero();
  Vec2 e = Vec2::Zero();
  Vec2 at(const Eigen::Vector4d& theta) const { return c * theta + e; }
};

struct Linear1 {
  Eigen::RowVector4d c = Eigen::RowVector4d::Zero();
  double e = 0.0;
  double at(const Eigen::Vector4d& theta) const { return c.dot(theta.transpose()) + e; }
};

struct TruthSample {
  double t = 0.0;
  Vec2 p = Vec2::Zero();
};

struct Increment {
  Linear2 odometry;  ///< A(t_b) − A(t_a)
  Vec2 z = Vec2::Zero();
  double travel = 0.0;
};

struct YawSample {
  double omega = 0.0, a_left = 0.0, a_right = 0.0;
  double dt = 0.0;  ///< the joint interval it stands for
};

/// The fit's parameters p = (s_L, ρ, B, c) — the left scale, the right one over it, the ICRs'
/// track B = y_ICR,L − y_ICR,R and centre c = (y_ICR,L + y_ICR,R) / 2 — as θ = (s_L, s_R, B, c),
/// the variables the odometry is linear in. (Not θ itself: the yaw rows below are homogeneous
/// in θ, and a fit in θ would shrink all of it to zero with the truth rows' weight.)
template <typename T>
Eigen::Matrix<T, 4, 1> thetaOf(const T* p) {
  return {p[0], p[1] * p[0], p[2], p[3]};
}

/// Horizontal truth displacement against the odometry's, rotated by the heading offset α.
struct IncrementResidual {
  Coef2 c;
  Vec2 e, z;
  double sigma = 1.0;
  template <typename T>
  bool operator()(const T* p, const T* alpha, T* r) const {
    const Eigen::Matrix<T, 4, 1> th = thetaOf(p);
    T m[2];
    for (int a = 0; a < 2; ++a) m[a] = T(e[a]) + c.row(a).cast<T>().dot(th.transpose());
    using std::cos;
    using std::sin;
    const T ca = cos(alpha[0]), sa = sin(alpha[0]);
    r[0] = (T(z[0]) - (ca * m[0] - sa * m[1])) / T(sigma);
    r[1] = (T(z[1]) - (sa * m[0] + ca * m[1])) / T(sigma);
    return true;
  }
};

/// The sides' speed difference against the one the gyro's yaw rate makes, in units of the left
/// side's nominal speed: ρ ā_R − ā_L − (B / s_L) ω (the error is the wheels': the gyro's is far
/// smaller, and a fit with the noisy difference as the regressor would bias B).
/// With `beta` > 0 the ratio B / s_L is held at it (a skid-steer rover whose ICRs the log
/// cannot tell: the yaw rows then inform ρ only, not the common scale through a track that is
/// not known).
struct YawResidual {
  YawSample y;
  double sigma = 1.0;
  double beta = 0.0;
  template <typename T>
  bool operator()(const T* p, T* r) const {
    const T b = beta > 0.0 ? T(beta) : p[2] / p[0];
    r[0] = (p[1] * T(y.a_right) - T(y.a_left) - b * T(y.omega)) / T(sigma);
    return true;
  }
};

double yawResidual(const YawSample& y, const Eigen::Vector4d& p, double beta) {
  double r = 0.0;
  YawResidual{y, 1.0, beta}(p.data(), &r);
  return r;
}

Vec2 incrementResidual(const Increment& inc, const Eigen::Vector4d& p, double alpha) {
  Vec2 r;
  IncrementResidual{inc.odometry.c, inc.odometry.e, inc.z, 1.0}(p.data(), &alpha, r.data());
  return r;
}

/// Lag-one correlation of a residual series (0 for fewer than 3 values).
double lag1(const std::vector<double>& r) {
  if (r.size() < 3) return 0.0;
  double num = 0.0, den = 0.0;
  for (size_t i = 0; i < r.size(); ++i) {
    den += r[i] * r[i];
    if (i + 1 < r.size()) num += r[i] * r[i + 1];
  }
  return den > 0.0 ? num / den : 0.0;
}

double inflation(double rho) {
  rho = std::clamp(rho, 0.0, 0.95);
  return std::sqrt((1.0 + rho) / (1.0 - rho));
}

}  // namespace

OdometryCalibration calibrateOdometry(const io::TraverseLog& log, const est::Trajectory& dr,
                                      const est::Segmentation& seg,
                                      const CalibrationOptions& options) {
  const io::Stream& j = log.joints;
  if (dr.nodes.size() != static_cast<size_t>(j.size()))
    throw std::invalid_argument("calibrateOdometry: dr must have one node per joint sample");
  OdometryCalibration out;

  // --- The truth: gps.csv (the antenna, per-fix σ) or truth.csv (the body origin). ---------------
  std::vector<TruthSample> truth;
  Vec3d lever = Vec3d::Zero();
  if (log.gps && !log.gps->empty()) {
    out.truth_file = "gps.csv";
    lever = log.config.gps.antenna_body_m;
    const PositionTruth pt(*log.gps, lever);
    for (const PositionFix& f : pt.fixes()) {
      truth.push_back({f.t, f.p_site.head<2>()});
    }
  } else if (log.truth && !log.truth->empty()) {
    out.truth_file = "truth.csv";
    const TruthTrajectory tt(*log.truth);
    for (Eigen::Index k = 0; k < log.truth->size(); ++k) {
      const double t = log.truth->t[k];
      truth.push_back({t, tt.position(t).head<2>()});
    }
  } else {
    throw InputError((log.dir / "gps.csv").string(), 0,
                     "calibration needs truth: the log has neither gps.csv nor truth.csv");
  }

  // --- The wheels: side, body y, URDF radius (the current scale taken out). ---------------------
  const rover::RoverGeometry& geo = log.geometry;
  const int nw = geo.numWheels();
  const auto kin = rover::forwardKinematics<double>(geo, geo.zeroJoints());
  const double s0l = log.config.odometry.wheel_radius_scale_left;
  const double s0r = log.config.odometry.wheel_radius_scale_right;
  const bool skid = log.config.skid_steer.has_value();
  enum Side { kLeft, kRight, kCentre };
  std::vector<Side> side(static_cast<size_t>(nw));
  std::vector<double> y(static_cast<size_t>(nw)), r_urdf(static_cast<size_t>(nw));
  double ysum[2] = {0, 0};
  int ycount[2] = {0, 0};
  for (int i = 0; i < nw; ++i) {
    const size_t u = static_cast<size_t>(i);
    y[u] = kin[i].T_body_wheel.p.y();
    side[u] = y[u] > 1e-6 ? kLeft : y[u] < -1e-6 ? kRight : kCentre;
    const double s0 = side[u] == kLeft ? s0l : side[u] == kRight ? s0r : 0.5 * (s0l + s0r);
    r_urdf[u] = geo.wheels[u].radius / s0;
    if (side[u] != kCentre && !geo.wheels[u].steered) ysum[side[u]] += y[u], ++ycount[side[u]];
  }
  // The ICRs' track B and centre c: rover.yaml's for skid steering, else the unsteered wheels'
  // mean y per side (held).
  double icr_l = ycount[0] ? ysum[0] / ycount[0] : 0.0;
  double icr_r = ycount[1] ? ysum[1] / ycount[1] : 0.0;
  if (skid)
    icr_l = log.config.skid_steer->icr_y_left_m, icr_r = log.config.skid_steer->icr_y_right_m;
  const Eigen::Vector4d theta0(s0l, s0r, icr_l - icr_r, 0.5 * (icr_l + icr_r));
  const bool yaw_possible = ycount[0] > 0 && ycount[1] > 0;

  // --- Dead reckoning's speed and the antenna's track, linear in θ. -----------------------------
  const Eigen::MatrixXd rates =
      rover::jointRates(std::span<const double>(j.t.data(), static_cast<size_t>(j.size())),
                        j.values, {log.config.joints.rate_filter_half_window});
  const double margin = (log.config.joints.rate_filter_half_window + 1) * io::medianPeriod(j);
  const double xc = geo.turn_centre_x;
  const Vec2 arm(lever.x() - xc, lever.y());  // turn centre → antenna (or body origin), body
  auto inRest = [&](double t) {
    for (const est::RestWindow& w : seg.rests)
      if (t >= w.t_start && t <= w.t_end) return true;
    return false;
  };
  std::vector<Linear2> track(static_cast<size_t>(j.size()));  // A_k
  std::vector<double> travel(static_cast<size_t>(j.size()), 0.0);
  std::vector<YawSample> yaws;
  Linear2 p;  // the turn centre, integrated
  Linear1 prev_speed;
  Vec2 prev_u = Vec2::Zero();
  for (Eigen::Index k = 0; k < j.size(); ++k) {
    const double t = j.t[k];
    const est::TrajectoryNode& n = dr.nodes[static_cast<size_t>(k)];
    const double omega = n.w_body.z();
    const Vec3d rpy = so3::rollPitchYaw(n.q_site_body);
    Linear1 speed;
    double used = 0.0, a_side[2] = {0, 0};
    int n_side[2] = {0, 0};
    for (int pass = 0; pass < 2 && used == 0.0; ++pass) {
      for (int i = 0; i < nw; ++i) {
        if (pass == 0 && !log.wheelUsed(i, t, margin)) continue;
        const size_t u = static_cast<size_t>(i);
        const double a = r_urdf[u] * rates(k, geo.wheels[u].coord);
        if (side[u] == kCentre) {
          speed.c[0] += 0.5 * a, speed.c[1] += 0.5 * a;
        } else {
          speed.c[side[u]] += a;
          // ω (y_ICR,side − y_i), y_ICR,side = c ± B/2
          if (skid) {
            speed.c[2] += (side[u] == kLeft ? 0.5 : -0.5) * omega, speed.c[3] += omega;
            speed.e -= omega * y[u];
          }
          if (!geo.wheels[u].steered && pass == 0) a_side[side[u]] += a, ++n_side[side[u]];
        }
        used += 1.0;
      }
    }
    speed.c /= used, speed.e /= used;
    const Vec2 u_k = std::cos(rpy.y()) * Vec2(std::cos(rpy.z()), std::sin(rpy.z()));
    if (k > 0) {
      const double dt = t - j.t[k - 1];
      p.c += 0.5 * dt * (prev_u * prev_speed.c + u_k * speed.c);
      p.e += 0.5 * dt * (prev_speed.e * prev_u + speed.e * u_k);
      travel[static_cast<size_t>(k)] =
          travel[static_cast<size_t>(k - 1)] +
          0.5 * dt * (std::abs(prev_speed.at(theta0)) + std::abs(speed.at(theta0)));
    }
    prev_speed = speed, prev_u = u_k;
    Linear2& a = track[static_cast<size_t>(k)];
    a = p;
    const double cy = std::cos(rpy.z()), sy = std::sin(rpy.z());
    a.e += Vec2(cy * arm.x() - sy * arm.y(), sy * arm.x() + cy * arm.y());
    if (yaw_possible && n_side[0] > 0 && n_side[1] > 0 && !inRest(t))
      yaws.push_back(
          {omega, a_side[0] / n_side[0], a_side[1] / n_side[1], k > 0 ? t - j.t[k - 1] : 0.0});
  }

  // --- Increments between truth samples at least increment_s apart. ----------------------------
  auto interp = [&](double t, Linear2& a, double& s) {
    const double* b = j.t.data();
    const Eigen::Index m =
        std::clamp<Eigen::Index>(std::upper_bound(b, b + j.size(), t) - b, 1, j.size() - 1);
    const double w = (t - j.t[m - 1]) / (j.t[m] - j.t[m - 1]);
    const Linear2& l0 = track[static_cast<size_t>(m - 1)];
    const Linear2& l1 = track[static_cast<size_t>(m)];
    a.c = (1 - w) * l0.c + w * l1.c, a.e = (1 - w) * l0.e + w * l1.e;
    s = (1 - w) * travel[static_cast<size_t>(m - 1)] + w * travel[static_cast<size_t>(m)];
  };
  std::vector<Increment> incs;
  const TruthSample* anchor = nullptr;
  for (const TruthSample& ts : truth) {
    if (j.size() < 2 || ts.t < j.t[0] || ts.t > j.t[j.size() - 1]) continue;
    if (anchor && ts.t < anchor->t + options.increment_s) continue;
    if (anchor) {
      Increment inc;
      Linear2 a0, a1;
      double s0 = 0.0, s1 = 0.0;
      interp(anchor->t, a0, s0);
      interp(ts.t, a1, s1);
      inc.odometry.c = a1.c - a0.c, inc.odometry.e = a1.e - a0.e;
      inc.z = ts.p - anchor->p;
      inc.travel = s1 - s0;
      if (inc.travel >= options.min_travel_m) incs.push_back(inc);
    }
    anchor = &ts;
  }
  if (incs.size() < 3) {
    throw InputError((log.dir / out.truth_file).string(), 0,
                     "too little motion to calibrate: " + std::to_string(incs.size()) +
                         " truth increments of at least " + std::to_string(options.min_travel_m) +
                         " m travel (need 3)");
  }
  for (const Increment& inc : incs) out.truth_path_m += inc.z.norm();

  // --- The fit: iteratively reweighted (each kind's σ), Huber loss. -----------------------------
  // What is fitted: the scales always; for skid steering the ICR track B when the log has yaw
  // rates, and the centre c when the fit can tell it (both dropped, in that order, when the
  // fit is singular or their σ is too large to mean anything: c > 0.1 m, B > 0.5 m).
  std::vector<int> free{0};  // no yaw rate: the sides' ratio held too
  if (!yaws.empty()) free = {0, 1};
  // The ICRs need turns: the yaw rate's variations must come from the wheels' differential,
  // which on a straight run they do not (terrain and timing wiggles are not the wheels' doing,
  // and would pull the track towards zero — test17run, 2.6 rad of turning, gave 0.07 m).
  double turned = 0.0;  // ∫|ω| dt over the yaw samples
  for (const YawSample& ys : yaws) turned += std::abs(ys.omega) * ys.dt;
  out.turned_rad = turned;
  const bool turns = turned >= options.min_turning_rad;
  if (skid && options.fit_icr && turns) free = {0, 1, 2, 3};
  // The wheels' own track (the unsteered wheels' mean y per side): a plausible ICR track is
  // within [0.5, 4] times it.
  const double wheel_track =
      (ycount[0] ? ysum[0] / ycount[0] : 0.0) - (ycount[1] ? ysum[1] / ycount[1] : 0.0);
  // B / s_L held (see YawResidual) while the ICRs of a skid-steer rover are.
  double beta = skid && free.size() < 4 ? theta0[2] / theta0[0] : 0.0;
  const Eigen::Vector4d p0(theta0[0], theta0[1] / theta0[0], theta0[2], theta0[3]);
  Eigen::Vector4d theta = p0;  // the fit's parameters p
  // α in closed form at the nominal θ: the rotation that best maps odometry onto truth.
  double alpha = 0.0;
  {
    double sc = 0.0, ss = 0.0;
    for (const Increment& inc : incs) {
      const Vec2 m = inc.odometry.at(theta0);
      sc += m.dot(inc.z), ss += m.x() * inc.z.y() - m.y() * inc.z.x();
    }
    alpha = std::atan2(ss, sc);
  }
  // One σ per kind of residual (the fixes' own σ weights nothing: a receiver's σ describes one
  // fix's error, most of which fixes seconds apart share — s5t1 declares 1.6–2.7 m per axis,
  // its 5 s increments scatter by 0.3–0.5 m — and the odometry's own error dominates RTK's).
  double sigma_i = 0.1, sigma_w = 0.01;  // m, m/s
  double f_inc = 1.0, f_yaw = 1.0;

  auto buildAndSolve = [&](const std::vector<int>& fit, double& a, Eigen::Vector4d& th,
                           ceres::Problem& pr) {
    pr.AddParameterBlock(th.data(), 4);
    std::vector<int> held;
    for (int i = 0; i < 4; ++i)
      if (std::find(fit.begin(), fit.end(), i) == fit.end()) held.push_back(i);
    if (held.size() == 4) {
      pr.SetParameterBlockConstant(th.data());
    } else if (!held.empty()) {
      pr.SetManifold(th.data(), new ceres::SubsetManifold(4, held));
    }
    pr.AddParameterBlock(&a, 1);
    for (const Increment& inc : incs) {
      auto* f = new ceres::AutoDiffCostFunction<IncrementResidual, 2, 4, 1>(
          new IncrementResidual{inc.odometry.c, inc.odometry.e, inc.z, f_inc * sigma_i});
      pr.AddResidualBlock(f, new ceres::HuberLoss(options.huber_k), th.data(), &a);
    }
    if (held.size() < 4) {
      for (const YawSample& ys : yaws) {
        auto* f = new ceres::AutoDiffCostFunction<YawResidual, 1, 4>(
            new YawResidual{ys, f_yaw * sigma_w, beta});
        pr.AddResidualBlock(f, new ceres::HuberLoss(options.huber_k), th.data());
      }
    }
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = 100;
    // The model is linear in θ: trust the Gauss-Newton step from the start (the yaw rows are far
    // stiffer than the truth rows, and LM's default damping on the scaled diagonal would crawl).
    so.initial_trust_region_radius = 1e12;
    so.function_tolerance = 1e-14;
    so.parameter_tolerance = 1e-14;
    so.gradient_tolerance = 1e-16;
    so.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &pr, &summary);
  };
  auto solve = [&](const std::vector<int>& fit, double& a, Eigen::Vector4d& th) {
    ceres::Problem pr;
    buildAndSolve(fit, a, th, pr);
  };
  // RMS of each kind at θ, α; with `update`, each kind's σ — robust: 1.4826 × the median
  // absolute residual (an RMS of the "inliers" of the current σ can only shrink, iteration by
  // iteration), the outliers beyond huber_k σ, and the lag-one correlations.
  auto residuals = [&](const Eigen::Vector4d& th, double a, ResidualGroup& gi, ResidualGroup& gy,
                       bool update) {
    std::vector<double> rx, ry, rw, abs_i, abs_w;
    double ss = 0.0, ssw = 0.0;
    for (const Increment& inc : incs) {
      const Vec2 e = incrementResidual(inc, th, a);
      ss += e.squaredNorm();
      rx.push_back(e.x()), ry.push_back(e.y());
      abs_i.push_back(std::abs(e.x())), abs_i.push_back(std::abs(e.y()));
    }
    for (const YawSample& ys : yaws) {
      const double e = yawResidual(ys, th, beta);
      rw.push_back(e), abs_w.push_back(std::abs(e));
      ssw += e * e;
    }
    gi.used = static_cast<int>(incs.size());
    gy.used = static_cast<int>(yaws.size());
    auto mad = [](std::vector<double> v) {
      if (v.empty()) return 0.0;
      std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
      return 1.4826 * v[v.size() / 2];
    };
    if (update) {
      // Exact data have no scatter: floors keep the weights finite.
      sigma_i = std::max(1e-4, mad(abs_i));
      if (!abs_w.empty()) sigma_w = std::max(1e-7, mad(abs_w));
      gi.noise_sigma = sigma_i, gy.noise_sigma = sigma_w;
      gi.lag1_correlation = 0.5 * (lag1(rx) + lag1(ry));
      gy.lag1_correlation = lag1(rw);
      gi.sigma_inflation = inflation(gi.lag1_correlation);
      gy.sigma_inflation = inflation(gy.lag1_correlation);
    }
    gi.outliers = gy.outliers = 0;
    for (size_t k = 0; k < incs.size(); ++k)
      if (std::hypot(rx[k], ry[k]) > options.huber_k * std::sqrt(2.0) * sigma_i) ++gi.outliers;
    for (double e : rw)
      if (std::abs(e) > options.huber_k * sigma_w) ++gy.outliers;
    const double rms_i = std::sqrt(ss / (2.0 * static_cast<double>(incs.size())));
    const double rms_w = yaws.empty() ? 0.0 : std::sqrt(ssw / static_cast<double>(yaws.size()));
    return std::pair{rms_i, rms_w};
  };

  // Before: the nominal θ, only α fitted.
  residuals(p0, alpha, out.increments, out.yaw_rates, true);
  solve({}, alpha, theta);
  {
    ResidualGroup gi, gy;
    const auto [ri, rw] = residuals(p0, alpha, gi, gy, false);
    out.increments.rms_before = ri, out.yaw_rates.rms_before = rw;
  }
  const double alpha0 = alpha;
  std::string icr_note = "held: not observable on this log";

  for (;;) {
    theta = p0, alpha = alpha0;
    f_inc = f_yaw = 1.0;
    for (int it = 0; it < options.reweight_iterations; ++it) {
      solve(free, alpha, theta);
      residuals(theta, alpha, out.increments, out.yaw_rates, true);
    }
    f_inc = out.increments.sigma_inflation, f_yaw = out.yaw_rates.sigma_inflation;
    ceres::Problem problem;
    buildAndSolve(free, alpha, theta, problem);
    const auto [ri, rw] = residuals(theta, alpha, out.increments, out.yaw_rates, false);
    out.increments.rms_after = ri, out.yaw_rates.rms_after = rw;

    // The covariance (JᵀJ)⁻¹ of the weighted, robustified residuals at the solution, by SVD, in
    // the free parameters and α: a singular value below 1e-9 of the largest is a direction
    // the log does not observe.
    ceres::Problem::EvaluateOptions eo;
    eo.parameter_blocks = {theta.data(), &alpha};
    ceres::CRSMatrix crs;
    problem.Evaluate(eo, nullptr, nullptr, nullptr, &crs);
    const int np = static_cast<int>(free.size());
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(crs.num_rows, crs.num_cols);
    for (int row = 0; row < crs.num_rows; ++row)
      for (int q = crs.rows[row]; q < crs.rows[row + 1]; ++q) J(row, crs.cols[q]) = crs.values[q];
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(J, Eigen::ComputeThinV);
    const Eigen::VectorXd sv = svd.singularValues();
    const bool ok =
        J.cols() == np + 1 && sv.size() == np + 1 && sv.minCoeff() > 1e-9 * sv.maxCoeff();
    Eigen::MatrixXd C;
    if (ok)
      C = svd.matrixV() * sv.cwiseInverse().cwiseAbs2().asDiagonal() * svd.matrixV().transpose();
    if (np == 4 && (!ok || C(3, 3) > 0.01)) {
      free = {0, 1, 2};  // the ICRs' centre: hold it
      continue;
    }
    if (np == 3 &&
        (!ok || C(2, 2) > 0.25 || theta[2] < 0.5 * wheel_track || theta[2] > 4.0 * wheel_track)) {
      free = {0, 1};  // the ICRs' track: hold it too
      beta = theta0[2] / theta0[0];
      icr_note = !ok || C(2, 2) > 0.25 ? "held: not observable on this log"
                                       : "held: the fit's track was implausible";
      continue;
    }
    if (np == 2 && !ok) {
      free = {0};  // the sides' ratio: hold it too
      continue;
    }
    if (!ok) {
      throw InputError((log.dir / out.truth_file).string(), 0,
                       "the odometry scales are not observable on this log (singular fit)");
    }
    // The full 4 × 4 covariance of θ (zero rows for the held ones), then rover.yaml's values.
    Eigen::Matrix4d Ct = Eigen::Matrix4d::Zero();
    for (int a = 0; a < np; ++a)
      for (int b = 0; b < np; ++b) Ct(free[a], free[b]) = C(a, b);
    auto fitted = [&](int i) { return std::find(free.begin(), free.end(), i) != free.end(); };
    auto add = [&](const char* key, double nominal, double value, double var, bool fit,
                   const std::string& note) {
      out.parameters.push_back({key, nominal, fit ? value : nominal,
                                fit ? std::sqrt(std::max(0.0, var)) : 0.0, fit, fit ? "" : note});
    };
    // rover.yaml's values from p, and their variances through the gradients.
    auto var = [&](const Eigen::RowVector4d& g) { return double(g * Ct * g.transpose()); };
    add("odometry.wheel_radius_scale_left", theta0[0], theta[0], Ct(0, 0), true, "");
    add("odometry.wheel_radius_scale_right", theta0[1], theta[1] * theta[0],
        var(Eigen::RowVector4d(theta[1], theta[0], 0, 0)), true, "");
    if (skid) {
      char buf[128];
      std::snprintf(buf, sizeof buf, "held: too little turning (%.1f rad, need %.1f)", turned,
                    options.min_turning_rad);
      const std::string note = !options.fit_icr ? "held (--no-icr)"
                               : yaws.empty()   ? "held: no yaw-rate sample"
                               : !turns         ? std::string(buf)
                                                : icr_note;
      // y_ICR,L = c + B/2, y_ICR,R = c − B/2.
      const Eigen::RowVector4d gl(0, 0, 0.5, 1), gr(0, 0, -0.5, 1);
      add("skid_steer.icr_y_left_m", icr_l, theta[3] + 0.5 * theta[2], var(gl), fitted(2), note);
      add("skid_steer.icr_y_right_m", icr_r, theta[3] - 0.5 * theta[2], var(gr), fitted(2), note);
      out.icr_centre_fitted = fitted(3);
    }
    const char* names[4] = {"wheel_radius_scale_left", "scale_right_over_left", "icr_track",
                            "icr_centre"};
    out.correlation.resize(np, np);
    for (int a = 0; a < np; ++a) {
      out.correlation_names.push_back(names[free[a]]);
      for (int b = 0; b < np; ++b)
        out.correlation(a, b) = C(a, b) / std::sqrt(std::max(1e-300, C(a, a) * C(b, b)));
    }
    out.mean_scale_sigma = std::sqrt(
        std::max(0.0, var(Eigen::RowVector4d(0.5 * (1 + theta[1]), 0.5 * theta[0], 0, 0))));
    out.heading_offset_rad = alpha;
    out.heading_offset_sigma_rad = std::sqrt(std::max(0.0, C(np, np)));
    return out;
  }
}

std::string calibrationOverlay(const OdometryCalibration& c, const std::string& source) {
  std::ostringstream os;
  char buf[256];
  os << "# Odometry calibration of " << source
     << " by `traverse calibrate` (docs/calibration.md).\n"
     << "# Apply with: traverse run LOGDIR --calibration THIS_FILE -o OUTDIR\n";
  std::snprintf(buf, sizeof buf,
                "# Fitted on %d increments of %s (%.1f m) and %d yaw-rate samples.\n",
                c.increments.used, c.truth_file.c_str(), c.truth_path_m, c.yaw_rates.used);
  os << buf;
  std::snprintf(buf, sizeof buf,
                "# Increments: RMS %.4g -> %.4g m per axis; sigma %.3g m; lag-1 correlation "
                "%.2f; %d outliers.\n",
                c.increments.rms_before, c.increments.rms_after, c.increments.noise_sigma,
                c.increments.lag1_correlation, c.increments.outliers);
  os << buf;
  std::snprintf(
      buf, sizeof buf,
      "# Yaw rates (sides' speed difference): RMS %.4g -> %.4g m/s; sigma %.3g m/s; lag-1 "
      "correlation %.2f; "
      "%d outliers.\n",
      c.yaw_rates.rms_before, c.yaw_rates.rms_after, c.yaw_rates.noise_sigma,
      c.yaw_rates.lag1_correlation, c.yaw_rates.outliers);
  os << buf;
  os << "# 1 sigma of each value in its comment (least squares, inflated for the residuals'\n"
     << "# correlation in time).\n"
     << "format: 1\n";
  std::string section;
  for (const CalibratedParameter& p : c.parameters) {
    if (!p.fitted) continue;
    const std::string sec = p.key.substr(0, p.key.find('.'));
    if (sec != section) os << sec << ":\n", section = sec;
    std::snprintf(buf, sizeof buf, "  %s: %.6g  # sigma %.2g (was %.6g)\n",
                  p.key.substr(p.key.find('.') + 1).c_str(), p.value, p.sigma, p.nominal);
    os << buf;
    if (p.key == "odometry.wheel_radius_scale_right") {  // what the fit leaves unknown
      std::snprintf(buf, sizeof buf,
                    "  wheel_radius_scale_sigma: %.2g  # the fitted mean scale's sigma\n"
                    "  wheel_radius_scale_side_sigma: 0  # the sides' difference is fitted\n",
                    c.mean_scale_sigma);
      os << buf;
    }
  }
  return os.str();
}

}  // namespace traverse::eval
