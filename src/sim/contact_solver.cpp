#include "traverse/sim/contact_solver.h"

#include <cmath>
#include <sstream>

#include <Eigen/Dense>

namespace traverse::sim {

ContactSolver::ContactSolver(const rover::RoverGeometry& geometry, const Terrain& terrain,
                             ContactSolverOptions options)
    : geometry_(geometry),
      suspension_(geometry.coordsOfKind(rover::CoordKind::kSuspension)),
      steering_(geometry.coordsOfKind(rover::CoordKind::kSteering)),
      terrain_(terrain),
      options_(options) {
  const auto kin = rover::forwardKinematics<double>(geometry_, geometry_.zeroJoints());
  const int nw = geometry_.numWheels();
  for (int i = 0; i < nw; ++i) {
    centre_height_ += (-kin[i].T_body_wheel.p.z() + geometry_.wheels[i].radius) / nw;
  }
  const double limit = 0.49 * M_PI;  // as lowestRimPoint
  const int n = options_.rim_scan_points;
  for (int k = 0; k < n; ++k) {
    const double candidate = -limit + 2.0 * limit * k / (n - 1);
    scan_xi_.push_back(candidate);
    scan_sin_.push_back(std::sin(candidate));
    scan_cos_.push_back(std::cos(candidate));
  }
}

Posed ContactSolver::bodyPose(double x, double y, double yaw, const ContactState& s) {
  return Posed{so3::fromRollPitchYaw(s.roll, s.pitch, yaw).toRotationMatrix(), Vec3d(x, y, s.z)};
}

rover::JointVectord ContactSolver::joints(const rover::JointVectord& suspension,
                                          const rover::JointVectord& steering) const {
  rover::JointVectord q = geometry_.zeroJoints();
  for (size_t c = 0; c < suspension_.size(); ++c)
    q[suspension_[c]] = suspension[static_cast<Eigen::Index>(c)];
  for (size_t c = 0; c < steering_.size(); ++c)
    q[steering_[c]] = steering[static_cast<Eigen::Index>(c)];
  return q;
}

std::vector<ContactSolver::Rim> ContactSolver::rims(const Posed& T_site_body,
                                                    const rover::JointVectord& q) const {
  const auto kin = rover::forwardKinematics<double>(geometry_, q);
  std::vector<Rim> out(kin.size());
  for (size_t i = 0; i < kin.size(); ++i) {
    const Posed w = T_site_body * kin[i].T_body_wheel;
    out[i] = {w.p, w.R.col(0), w.R.col(2), geometry_.wheels[i].radius};
  }
  return out;
}

// Vertical gap between the rim point at ξ and the terrain below it.
double ContactSolver::gap(const Rim& rim, double xi) const {
  return gap(rim, std::sin(xi), std::cos(xi));
}

double ContactSolver::gap(const Rim& rim, double sin_xi, double cos_xi) const {
  const Vec3d p = rim.centre + rim.radius * (sin_xi * rim.x_axis - cos_xi * rim.z_axis);
  return p.z() - terrain_.height(p.x(), p.y());
}

// d gap / dξ = (rim tangent) · (−f_x, −f_y, 1): zero exactly where the rim is tangent to the
// surface.
double ContactSolver::gapSlope(const Rim& rim, double xi) const {
  const Vec3d p = rim.centre + rim.radius * (std::sin(xi) * rim.x_axis - std::cos(xi) * rim.z_axis);
  const Vec3d tangent = rim.radius * (std::cos(xi) * rim.x_axis + std::sin(xi) * rim.z_axis);
  const Vec2d g = terrain_.gradient(p.x(), p.y());
  return tangent.z() - g.x() * tangent.x() - g.y() * tangent.y();
}

// Minimises the gap over the rim's lower half: Newton on gapSlope = 0 from xi_start, then a
// global scan guards against a lower point elsewhere (a wheel meeting a step edge).
double ContactSolver::lowestRimPoint(const Rim& rim, double xi_start) const {
  const double limit = 0.49 * M_PI;
  auto newton = [&](double xi) {
    for (int it = 0; it < 30; ++it) {
      const double s = gapSlope(rim, xi);
      const double h = 1e-6;
      const double curvature = (gapSlope(rim, xi + h) - gapSlope(rim, xi - h)) / (2 * h);
      double step = curvature > 1e-9 ? -s / curvature : -s / rim.radius;
      step = std::clamp(step, -0.2, 0.2);
      xi = std::clamp(xi + step, -limit, limit);
      if (std::abs(step) < 1e-13) break;
    }
    return xi;
  };
  double xi = newton(xi_start);
  double best = gap(rim, xi);
  for (size_t k = 0; k < scan_xi_.size(); ++k) {
    const double candidate = scan_xi_[k];
    if (gap(rim, scan_sin_[k], scan_cos_[k]) < best - 1e-7) {
      const double refined = newton(candidate);
      const double g = gap(rim, refined);
      if (g < best) best = g, xi = refined;
    }
  }
  return xi;
}

ContactState ContactSolver::initialGuess(double x, double y, double yaw) const {
  ContactState s;
  const Vec3d n = terrain_.normal(x, y);
  const Mat3d Rz = so3::fromRollPitchYaw(0.0, 0.0, yaw).toRotationMatrix();
  const Vec3d nb = Rz.transpose() * n;  // normal in the heading frame
  s.pitch = std::atan2(nb.x(), nb.z());
  s.roll = std::atan2(-nb.y(), std::hypot(nb.x(), nb.z()));
  s.z = terrain_.height(x, y) + centre_height_;
  s.suspension = rover::JointVectord::Zero(static_cast<Eigen::Index>(suspension_.size()));
  s.xi = rover::WheelVectord::Zero(geometry_.numWheels());
  return s;
}

ContactState ContactSolver::solve(double x, double y, double yaw,
                                  const rover::JointVectord& steering,
                                  const ContactState& guess) const {
  const int nw = geometry_.numWheels();
  const auto ns = static_cast<Eigen::Index>(suspension_.size());
  const Eigen::Index nu = 3 + ns;  // unknowns: z, roll, pitch, suspension angles
  auto unpack = [&](const Eigen::VectorXd& u, ContactState s) {
    s.z = u[0], s.roll = u[1], s.pitch = u[2], s.suspension = u.tail(ns);
    return s;
  };
  auto gaps = [&](const Eigen::VectorXd& u, const rover::WheelVectord& xi) {
    const ContactState s = unpack(u, {});
    const auto r = rims(bodyPose(x, y, yaw, s), joints(s.suspension, steering));
    Eigen::VectorXd g(nw);
    for (int i = 0; i < nw; ++i) g[i] = gap(r[i], xi[i]);
    return g;
  };
  ContactState state = guess;
  if (state.xi.size() != nw) state.xi = rover::WheelVectord::Zero(nw);
  Eigen::VectorXd u(nu);
  u << guess.z, guess.roll, guess.pitch,
      guess.suspension.size() == ns ? Eigen::VectorXd(guess.suspension) : Eigen::VectorXd::Zero(ns);
  const bool square = nu == nw;
  for (int it = 0; it < options_.max_iterations; ++it) {
    // Contact angles for the current configuration, then the gaps there.
    const auto r = rims(bodyPose(x, y, yaw, unpack(u, state)), joints(u.tail(ns), steering));
    for (int i = 0; i < nw; ++i) state.xi[i] = lowestRimPoint(r[i], state.xi[i]);
    const Eigen::VectorXd F = gaps(u, state.xi);
    if (F.cwiseAbs().maxCoeff() < options_.tolerance_m) return unpack(u, state);
    // At the rim minimum ∂gap/∂ξ = 0, so the Jacobian can hold ξ fixed (envelope theorem).
    Eigen::MatrixXd J(nw, nu);
    for (Eigen::Index j = 0; j < nu; ++j) {
      const double h = 1e-7;
      Eigen::VectorXd up = u, um = u;
      up[j] += h, um[j] -= h;
      J.col(j) = (gaps(up, state.xi) - gaps(um, state.xi)) / (2 * h);
    }
    const Eigen::VectorXd step =
        square ? Eigen::VectorXd(J.fullPivLu().solve(-F))
               : Eigen::VectorXd(J.colPivHouseholderQr().solve(-F));  // least squares
    double alpha = 1.0;  // backtrack if the gaps do not shrink
    while (alpha > 1e-3 && gaps(u + alpha * step, state.xi).norm() > F.norm()) alpha *= 0.5;
    u += alpha * step;
    if (!u.allFinite() ||
        (ns > 0 && u.tail(ns).cwiseAbs().maxCoeff() > options_.max_joint_angle_rad))
      break;
    // More wheels than unknowns: the least-squares optimum, once Gauss–Newton stops moving.
    if (!square && alpha * step.norm() < 1e-10) return unpack(u, state);
  }
  // Least squares: the optimum once Gauss–Newton has stalled, if no wheel floats or sinks by
  // more than a centimetre (a rigid rover on rough ground rests on three of its wheels).
  if (!square && u.allFinite()) {
    const auto r = rims(bodyPose(x, y, yaw, unpack(u, state)), joints(u.tail(ns), steering));
    for (int i = 0; i < nw; ++i) state.xi[i] = lowestRimPoint(r[i], state.xi[i]);
    if (gaps(u, state.xi).cwiseAbs().maxCoeff() < 0.01) return unpack(u, state);
  }
  std::ostringstream os;
  os << "contact solver: no contact configuration at x = " << x << " m, y = " << y
     << " m, yaw = " << yaw << " rad (suspension angles " << u.tail(ns).transpose() << ")";
  throw ContactError(os.str());
}

std::vector<WheelContactCheck> ContactSolver::check(double x, double y, double yaw,
                                                    const rover::JointVectord& steering,
                                                    const ContactState& s) const {
  const auto r = rims(bodyPose(x, y, yaw, s), joints(s.suspension, steering));
  std::vector<WheelContactCheck> out(r.size());
  for (size_t i = 0; i < r.size(); ++i) {
    const Rim& rim = r[i];
    const double xi = s.xi[i];
    const Vec3d p =
        rim.centre + rim.radius * (std::sin(xi) * rim.x_axis - std::cos(xi) * rim.z_axis);
    const Vec3d tangent = (std::cos(xi) * rim.x_axis + std::sin(xi) * rim.z_axis).normalized();
    out[i].gap_m = gap(rim, xi);
    out[i].tangency_rad =
        std::asin(std::min(1.0, std::abs(tangent.dot(terrain_.normal(p.x(), p.y())))));
    out[i].min_rim_gap_m = out[i].gap_m;
    for (int k = 0; k <= 720; ++k) {
      out[i].min_rim_gap_m = std::min(out[i].min_rim_gap_m, gap(rim, -0.5 * M_PI + M_PI * k / 720));
    }
  }
  return out;
}

}  // namespace traverse::sim
