// Reference path of the turn-centre point: legs with quintic speed ramps (the "5th-order spline"
// of the paper's controller, K §4.2) or one smooth bump per leg (slow onset, no cruise),
// Ackermann steering of the front wheels (K §2.3.4).
#include <cmath>

#include "traverse/sim/simulator.h"

namespace traverse::sim {
namespace {

double smoothstep(double u) {
  return u <= 0 ? 0 : u >= 1 ? 1 : u * u * u * (10 - 15 * u + 6 * u * u);
}
// ∫₀ᵘ smoothstep = 2.5u⁴ − 3u⁵ + u⁶
double smoothstepIntegral(double u) {
  return u <= 0 ? 0 : u >= 1 ? u - 0.5 : u * u * u * u * (2.5 - 3 * u + u * u);
}

/// The first wheel each steering coordinate turns (its joint on the wheel's chain).
std::vector<int> steeredWheels(const rover::RoverGeometry& geo) {
  std::vector<int> out;
  for (const int c : geo.coordsOfKind(rover::CoordKind::kSteering)) {
    int wheel = -1;
    for (int w = 0; w < geo.numWheels() && wheel < 0; ++w) {
      for (int j = geo.wheels[w].drive_joint; j >= 0; j = geo.joints[j].parent)
        if (geo.joints[j].coord == c) wheel = w;
    }
    out.push_back(wheel);
  }
  return out;
}

/// Steering of the steered wheels (at zero suspension angles) that puts the instantaneous
/// centre of rotation at (x_c, R) in the body; a turn in place is R = 0.
rover::JointVectord steeringFor(const rover::RoverGeometry& geo, const Leg& leg) {
  const std::vector<int> wheels = steeredWheels(geo);
  rover::JointVectord s = rover::JointVectord::Zero(static_cast<Eigen::Index>(wheels.size()));
  if (leg.kind != Leg::Kind::kArc && leg.kind != Leg::Kind::kTurnInPlace) return s;
  const auto kin = rover::forwardKinematics<double>(geo, geo.zeroJoints());
  for (Eigen::Index k = 0; k < s.size(); ++k) {
    const int w = wheels[static_cast<size_t>(k)];
    if (w < 0) continue;  // a steering joint above no wheel
    const Vec3d p = kin[static_cast<size_t>(w)].T_body_wheel.p;
    const double dx = p.x() - geo.turn_centre_x;
    s[k] = leg.kind == Leg::Kind::kTurnInPlace ? -std::atan(dx / p.y())
                                               : std::atan(dx / (leg.radius_m - p.y()));
  }
  return s;
}

}  // namespace

SpeedProfile::SpeedProfile(Leg::Profile k, double a, double c, double r)
    : kind(k), amount(a), cruise(c), ramp(r), cruise_time(0.0) {
  if (kind == Leg::Profile::kSmooth) return;
  if (amount < cruise * ramp) cruise = amount / ramp;  // too short to reach cruise speed
  cruise_time = (amount - cruise * ramp) / cruise;
}

double SpeedProfile::duration() const {
  if (kind == Leg::Profile::kSmooth) return amount * (15.0 / 8.0) / cruise;
  return 2 * ramp + cruise_time;
}

double SpeedProfile::rate(double t) const {
  if (kind == Leg::Profile::kSmooth) {
    const double T = duration(), u = t / T;
    if (u <= 0 || u >= 1) return 0;
    return amount / T * 30 * u * u * (1 - u) * (1 - u);  // d/dt amount·smoothstep(t/T)
  }
  if (t < ramp) return cruise * smoothstep(t / ramp);
  if (t < ramp + cruise_time) return cruise;
  return cruise * smoothstep((duration() - t) / ramp);
}

double SpeedProfile::position(double t) const {
  if (t <= 0) return 0;
  if (t >= duration()) return amount;
  if (kind == Leg::Profile::kSmooth) return amount * smoothstep(t / duration());
  if (t < ramp) return cruise * ramp * smoothstepIntegral(t / ramp);
  if (t < ramp + cruise_time) return 0.5 * cruise * ramp + cruise * (t - ramp);
  return amount - cruise * ramp * smoothstepIntegral((duration() - t) / ramp);
}

std::vector<PathSample> samplePath(const Scenario& sc, const rover::RoverGeometry& geo) {
  const double dt = 1.0 / sc.truth_rate_hz;
  std::vector<PathSample> out;
  Vec2d centre = sc.start.head<2>();
  double yaw = sc.start.z(), t0 = 0.0;
  rover::JointVectord steering = rover::JointVectord::Zero(
      static_cast<Eigen::Index>(geo.coordsOfKind(rover::CoordKind::kSteering).size()));
  auto emit_until = [&](double duration, auto&& at) {  // samples in [t0, t0 + duration)
    const long first = std::lround(std::ceil(t0 / dt - 1e-9));
    for (long k = first; k * dt < t0 + duration - 1e-9; ++k) out.push_back(at(k * dt - t0, k * dt));
    t0 += duration;
  };
  for (const Leg& leg : sc.legs) {
    if (leg.kind == Leg::Kind::kRest) {
      emit_until(leg.duration_s, [&](double, double t) {
        return PathSample{t, centre, yaw, steering, 0, 0, 0, false};
      });
      continue;
    }
    const rover::JointVectord target = steeringFor(geo, leg);
    if (target.size() > 0 && (target - steering).cwiseAbs().maxCoeff() > 1e-12) {
      const rover::JointVectord from = steering;
      emit_until(leg.steer_s, [&](double tau, double t) {
        return PathSample{t, centre, yaw, from + (target - from) * smoothstep(tau / leg.steer_s),
                          0, 0,      0,   false};
      });
      steering = target;
    }
    const bool turn = leg.kind == Leg::Kind::kTurnInPlace;
    const double amount = turn ? leg.angle_rad : leg.distance_m;
    const double sign = amount < 0 ? -1.0 : 1.0;
    const SpeedProfile prof(leg.profile, std::abs(amount), turn ? leg.rate_rad_s : leg.speed_mps,
                            leg.ramp_s);
    const Vec2d c0 = centre;
    const double yaw0 = yaw;
    auto pose = [&](double s, Vec2d* c, double* y) {  // s: signed distance or angle travelled
      if (leg.kind == Leg::Kind::kStraight) {
        *c = c0 + s * Vec2d(std::cos(yaw0), std::sin(yaw0)), *y = yaw0;
      } else if (turn) {
        *c = c0, *y = yaw0 + s;
      } else {
        const double R = leg.radius_m;
        *y = yaw0 + s / R;
        *c = c0 + R * Vec2d(std::sin(*y) - std::sin(yaw0), -std::cos(*y) + std::cos(yaw0));
      }
    };
    emit_until(prof.duration(), [&](double tau, double t) {
      PathSample p{t, {}, 0, steering, 0, 0, prof.rate(tau) / prof.cruise, true};
      pose(sign * prof.position(tau), &p.centre, &p.yaw);
      const double rate = sign * prof.rate(tau);
      p.speed_mps = turn ? 0.0 : rate;
      p.yaw_rate_rad_s = turn ? rate : leg.kind == Leg::Kind::kArc ? rate / leg.radius_m : 0.0;
      return p;
    });
    pose(amount, &centre, &yaw);
  }
  out.push_back(PathSample{t0, centre, yaw, steering, 0, 0, 0, false});
  return out;
}

}  // namespace traverse::sim
