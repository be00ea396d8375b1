// Truth generation: contact configuration along the path, velocities by central differences,
// wheel drive angles from rolling at the contact point plus injected slip (K §4: "uses the
// contact geometry ... to derive wheel motion").
#include "traverse/sim/simulator.h"

#include <cmath>
#include <memory>
#include <stdexcept>

#include "sim/sensor_synthesis.h"
#include "traverse/io/rover_description.h"
#include "traverse/rover/nominal_slip.h"
#include "traverse/sim/random.h"
#include "traverse/sim/terrain.h"

namespace traverse::sim {
namespace {

std::shared_ptr<const Terrain> makeTerrain(const TerrainSpec& t, const Scenario& sc,
                                           uint64_t seed) {
  if (t.type == "plane") return std::make_shared<PlaneTerrain>(t.slope_rad, t.direction_rad);
  if (t.type == "undulating") return std::make_shared<UndulatingTerrain>();
  if (t.type == "step") {
    return std::make_shared<StepTerrain>(t.step_height_m, t.step_x_m, t.step_y_min_m,
                                         t.step_y_max_m, t.step_ramp_m);
  }
  if (t.type == "rough") {
    // Cover the whole path with a margin.
    double reach = 0;
    for (const Leg& l : sc.legs)
      reach +=
          std::abs(l.distance_m) * (l.kind == Leg::Kind::kStraight || l.kind == Leg::Kind::kArc);
    RoughTerrain::Options o;
    o.rms_height_m = t.rms_height_m;
    o.correlation_length_m = t.correlation_length_m;
    o.bumps_per_m2 = t.bumps_per_m2;
    o.x_min = sc.start.x() - reach - 3, o.x_max = sc.start.x() + reach + 3;
    o.y_min = sc.start.y() - reach - 3, o.y_max = sc.start.y() + reach + 3;
    o.seed = static_cast<unsigned>(seed * 7919 + 17);
    auto rough = std::make_shared<RoughTerrain>(o);
    if (t.base_slope_rad == 0.0) return rough;
    return std::make_shared<SumTerrain>(std::vector<std::shared_ptr<const Terrain>>{
        rough, std::make_shared<PlaneTerrain>(t.base_slope_rad, 0.0)});
  }
  return std::make_shared<FlatTerrain>(0.0);
}

/// Injected longitudinal slip per wheel: white + first-order Gauss–Markov + bursts, scaled by
/// how fast the rover is moving relative to its cruise rate (no slip at rest).
class SlipProcess {
 public:
  SlipProcess(const SlipSpec& s, const FaultSpec& f, int wheels, double dt, uint64_t seed)
      : s_(s),
        f_(f),
        dt_(dt),
        rng_(seed, 101),
        burst_rng_(seed, 102),
        gm_(rover::WheelVectord::Zero(wheels)) {}
  rover::WheelVectord step(double t, double progress, double distance_step) {
    const double a = std::exp(-dt_ / s_.correlation_time_s);
    rover::WheelVectord out = rover::WheelVectord::Zero(gm_.size());
    if (s_.burst_rate_per_m > 0 && burst_rng_.uniform() < s_.burst_rate_per_m * distance_step)
      burst_left_ = s_.burst_duration_s;
    const double burst = burst_left_ > 0 ? s_.burst_mps : 0.0;
    burst_left_ -= dt_;
    for (Eigen::Index i = 0; i < gm_.size(); ++i) {
      gm_[i] = a * gm_[i] + std::sqrt(1 - a * a) * s_.longitudinal_correlated_mps * rng_.normal();
      out[i] = progress * (s_.longitudinal_white_mps * rng_.normal() + gm_[i] + burst);
    }
    lateral_ = a * lateral_ + std::sqrt(1 - a * a) * s_.lateral_correlated_mps * rng_.normal();
    // The injected slip burst fault (FaultSpec): added only inside its window, so a scenario
    // without it gives the same numbers bit for bit.
    in_fault_burst_ = f_.slip_burst.contains(t);
    if (in_fault_burst_) {
      for (Eigen::Index i = 0; i < out.size(); ++i) {
        if (f_.slip_burst_wheel == 0 || f_.slip_burst_wheel == i + 1)
          out[i] += progress * f_.slip_burst_longitudinal_mps;
      }
    }
    return out;
  }
  double lateral(double progress) const {
    return in_fault_burst_ ? progress * (lateral_ + f_.slip_burst_lateral_mps)
                           : progress * lateral_;
  }

 private:
  SlipSpec s_;
  FaultSpec f_;
  bool in_fault_burst_ = false;
  double dt_;
  Rng rng_, burst_rng_;
  rover::WheelVectord gm_;
  double lateral_ = 0.0, burst_left_ = 0.0;
};

/// Contact solution at every path sample (rests reuse the previous solution).
std::vector<TruthSample> solvePoses(const Scenario& sc, const rover::RoverGeometry& geo,
                                    const Terrain& terrain, const std::vector<PathSample>& path,
                                    SlipProcess& slip) {
  const ContactSolver solver(geo, terrain);
  const double ground_height = solver.bodyHeightAboveGround();
  std::vector<TruthSample> truth(path.size());
  ContactState state;
  Vec2d body_xy = Vec2d::Zero();
  Vec2d lateral_offset = Vec2d::Zero();
  const double dt = 1.0 / sc.truth_rate_hz;
  for (size_t k = 0; k < path.size(); ++k) {
    const PathSample& p = path[k];
    TruthSample& s = truth[k];
    s.t = p.t;
    s.moving = p.moving;
    s.progress = p.progress;
    const double step = std::abs(p.speed_mps) * dt;
    s.slip_longitudinal_mps = slip.step(p.t, p.progress, step);
    lateral_offset += slip.lateral(p.progress) * dt * Vec2d(-std::sin(p.yaw), std::cos(p.yaw));
    // The path is that of the ground point below the turn centre, (x_c, 0, −h) in the body, h the
    // body origin's height above the ground at zero joint angles: a rover rolling or pitching
    // about a point between its contacts does not drag its wheels sideways or back, as one
    // pivoting about a point 0.19 m up would. The body origin follows by fixed-point iteration
    // with the contact solution (the offset depends on roll and pitch).
    const Vec2d ref = p.centre + lateral_offset;
    const bool same = k > 0 && !p.moving && path[k - 1].centre == p.centre &&
                      path[k - 1].yaw == p.yaw && path[k - 1].steering == p.steering &&
                      !path[k - 1].moving;
    // At rest (same reference pose) keep the previous solution, body position included.
    if (k == 0) body_xy = ref - geo.turn_centre_x * Vec2d(std::cos(p.yaw), std::sin(p.yaw));
    if (k == 0) state = solver.initialGuess(body_xy.x(), body_xy.y(), p.yaw);
    for (int it = 0; it < 4 && !same; ++it) {
      const Mat3d R = so3::fromRollPitchYaw(state.roll, state.pitch, p.yaw).toRotationMatrix();
      const Vec2d next = ref - (R * Vec3d(geo.turn_centre_x, 0.0, -ground_height)).head<2>();
      const bool converged = it > 0 && (next - body_xy).norm() < 1e-10;
      body_xy = next;
      state = solver.solve(body_xy.x(), body_xy.y(), p.yaw, p.steering, state);
      if (converged) break;
    }
    const Posed pose = ContactSolver::bodyPose(body_xy.x(), body_xy.y(), p.yaw, state);
    s.p_site = pose.p;
    s.q_site_body = Quatd(pose.R).normalized();
    s.joints = geo.zeroJoints();
    const std::vector<int> suspension = geo.coordsOfKind(rover::CoordKind::kSuspension);
    const std::vector<int> steering = geo.coordsOfKind(rover::CoordKind::kSteering);
    for (size_t c = 0; c < suspension.size(); ++c)
      s.joints[suspension[c]] = state.suspension[static_cast<Eigen::Index>(c)];
    for (size_t c = 0; c < steering.size(); ++c)
      s.joints[steering[c]] = p.steering[static_cast<Eigen::Index>(c)];
    s.joint_rates = geo.zeroJoints();
    s.xi = state.xi;
    s.cmd = rover::nominalBodyTwist(geo, p.speed_mps, p.yaw_rate_rad_s);
  }
  return truth;
}

/// v, ω, γ̇, λ̇ by central differences; then v̇, ω̇; one-sided at the ends.
void differentiate(std::vector<TruthSample>& truth, const rover::RoverGeometry& geo) {
  const size_t n = truth.size();
  auto span = [&](size_t k) {
    return std::pair<size_t, size_t>{k == 0 ? 0 : k - 1, k + 1 >= n ? n - 1 : k + 1};
  };
  for (size_t k = 0; k < n; ++k) {
    const auto [a, b] = span(k);
    if (a == b) continue;
    const double h = truth[b].t - truth[a].t;
    TruthSample& s = truth[k];
    s.v_body = s.q_site_body.conjugate() * ((truth[b].p_site - truth[a].p_site) / h);
    s.w_body = so3::boxminus(truth[b].q_site_body, truth[a].q_site_body) / h;
    // ω from the chord is expressed in frame a; rotate to the frame at k (second-order accurate).
    s.w_body = s.q_site_body.conjugate() * (truth[a].q_site_body * s.w_body);
    // Suspension and steering rates (the drive rates follow from rolling, driveWheels).
    for (const rover::Coordinate& c : geo.coords) {
      if (c.kind == rover::CoordKind::kDrive) continue;
      const auto j = &c - geo.coords.data();
      s.joint_rates[j] = (truth[b].joints[j] - truth[a].joints[j]) / h;
    }
  }
  for (size_t k = 0; k < n; ++k) {
    const auto [a, b] = span(k);
    if (a == b) continue;
    const double h = truth[b].t - truth[a].t;
    truth[k].a_body = (truth[b].v_body - truth[a].v_body) / h;
    truth[k].w_dot_body = (truth[b].w_body - truth[a].w_body) / h;
  }
}

/// Wheel drive rates from rolling at the contact point: the slip constraint's longitudinal row
/// is linear in ψ̇_i with slope −r, so ψ̇_i = (t_x(ψ̇_i = 0) − s_i)/r gives contact slip s_i.
void driveWheels(std::vector<TruthSample>& truth, const rover::RoverGeometry& geo) {
  for (size_t k = 0; k < truth.size(); ++k) {
    TruthSample& s = truth[k];
    const auto kin = rover::forwardKinematics<double>(geo, s.joints);
    rover::JointVectord rates = s.joint_rates;
    for (const rover::Wheel& w : geo.wheels) rates[w.coord] = 0.0;
    for (int i = 0; i < geo.numWheels(); ++i) {
      const double r = geo.wheels[i].radius;
      const Vec4d t0 = rover::slipConstraint<double>(kin[i].T_body_wheel, r,
                                                     rover::wheelJointTwist(kin[i], rates),
                                                     s.v_body, s.w_body, s.xi[i]);
      // A skid-steered side rolls at the speed of its centre of rotation (io::SkidSteerConfig):
      // the nominal longitudinal slip ω_z · icr_offset_y, as rover::nominalSlip models it.
      const double nominal = s.w_body.z() * geo.wheels[i].icr_offset_y;
      s.joint_rates[geo.wheels[i].coord] = (t0[0] - nominal - s.slip_longitudinal_mps[i]) / r;
    }
    if (k > 0) {  // trapezoidal integration of the drive angles
      const double h = s.t - truth[k - 1].t;
      for (const rover::Wheel& w : geo.wheels) {
        s.joints[w.coord] = truth[k - 1].joints[w.coord] +
                            0.5 * h * (s.joint_rates[w.coord] + truth[k - 1].joint_rates[w.coord]);
      }
    }
  }
}

void gyroBias(std::vector<TruthSample>& truth, const SensorSpec& s, uint64_t seed) {
  Rng rng(seed, 201);
  Vec3d b = s.gyro_bias_rad_s;
  for (size_t k = 0; k < truth.size(); ++k) {
    if (k > 0) {
      const double q =
          s.gyro_bias_random_walk_rad_s_per_sqrt_s * std::sqrt(truth[k].t - truth[k - 1].t);
      b += q * Vec3d(rng.normal(), rng.normal(), rng.normal());
    }
    truth[k].gyro_bias = b;
  }
}

}  // namespace

Simulation simulate(const Scenario& sc, const std::filesystem::path& rover_dir, uint64_t seed) {
  io::RoverConfig config = io::loadRoverConfig(rover_dir / "rover.yaml");
  const rover::RoverGeometry geo = io::loadRoverGeometry(rover_dir / config.urdf_file, config);
  const auto terrain = makeTerrain(sc.terrain, sc, seed);
  checkFaults(sc, geo);
  const std::vector<PathSample> path = samplePath(sc, geo);
  SlipProcess slip(sc.slip, sc.faults, geo.numWheels(), 1.0 / sc.truth_rate_hz, seed);
  Simulation sim;
  sim.truth = solvePoses(sc, geo, *terrain, path, slip);
  differentiate(sim.truth, geo);
  driveWheels(sim.truth, geo);
  gyroBias(sim.truth, sc.sensors, seed);
  sim.log = synthesizeLog(sc, config, geo, rover_dir, sim.truth, seed);
  applyFaults(sc, sim.log.config, geo, sim.truth, sim.log, seed);
  return sim;
}

Simulation withSensorFaults(Simulation clean, const Scenario& sc, uint64_t seed) {
  if (!sc.faults.slip_burst.empty())
    throw std::invalid_argument("withSensorFaults: a slip burst is in the physics: simulate it");
  checkFaults(sc, clean.log.geometry);
  applyFaults(sc, clean.log.config, clean.log.geometry, clean.truth, clean.log, seed);
  return clean;
}

}  // namespace traverse::sim
