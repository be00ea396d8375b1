// rover.yaml: sensor set-up, noise defaults, gravity, sun direction, joint ↔ column map.
//
// Every default lives in this header (the one place docs/log-format.md points to). Units are
// in the key names. A missing key takes its default; a key of the wrong type or out of range
// is an InputError naming the key.
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "traverse/core/types.h"
#include "traverse/rover/joint_sample.h"

namespace traverse::io {

enum class GyroAxes { kHeadingOnly, kThreeAxis };

struct GyroConfig {
  GyroAxes axes = GyroAxes::kHeadingOnly;  ///< `axes: z` (B_g = [0 0 1], K-13) or `xyz`
  double noise_rad_s = 0.0031;             ///< white noise, 1σ per sample (R §4.3: 0.0031 rad/s)
  double bias_random_walk_rad_s_per_sqrt_s = 1e-5;  ///< bias random walk density (K-9)
  double initial_bias_sigma_rad_s = 0.005;          ///< prior σ of the bias before any rest
  /// Density of the EKF's rate perturbation ω_p on the gyro's measured axes (rad/s²/√Hz, with
  /// process.rate_time_constant_s): how far the body rate may depart from the bias-corrected
  /// gyro beyond its white noise — its scale and misalignment errors. Unset: 0.1 × the process
  /// rate noise (O §2.2.1: "small"). A good gyro wants it far smaller: every other row that
  /// sees ω (a skid-steer rover's slip rows in a turn) can pull the rate that far.
  std::optional<double> rate_perturbation_rad_s2_per_sqrt_hz;
};

struct SunSensorConfig {
  Mat3d R_body_sensor = Mat3d::Identity();  ///< `mounting_rpy_rad` (sensor → body)
  double field_of_view_rad = 2.7925268;     ///< full cone angle: 160° (K §1.3, WASS)
  double noise = 0.005;                     ///< 1σ of s1, s2 (dimensionless; ≈0.45° per 0.005)
};

struct AccelConfig {
  Vec3d lever_arm_m = Vec3d::Zero();  ///< L^b: body origin → accelerometer (K-10)
  double noise_mps2 = 0.01;           ///< white noise, 1σ per sample
  /// The accelerometer's bias b_a (body axes, m/s²): 1σ per axis at the log's start. Above 0
  /// the EKF and the smoother estimate it (three states; a_m = K-10 + b_a), observed at rests
  /// through gravity (as the attitude changes between them) and, with the accelerometer
  /// driving the velocity, by the wheels; 0: the readings are taken as unbiased (no states).
  double bias_sigma_mps2 = 0.0;
  /// Its random walk (m/s²/√s; K-9's form for the accelerometer): 0 is a constant bias.
  double bias_random_walk_mps2_per_sqrt_s = 0.0;
  bool hasBias() const { return bias_sigma_mps2 > 0.0; }
};

/// The inertial measurement unit's mounting: gyro.csv and accel.csv are read in the IMU's own
/// axes and turned into the body frame (f_body = R_body_imu f_imu) as the log is read, so every
/// estimator sees body-frame readings (io::readLog; the log's config then says identity).
struct ImuConfig {
  Mat3d R_body_imu = Mat3d::Identity();  ///< `imu.mounting_rpy_rad` (IMU → body, Z-Y-X)
  bool mounted() const { return !R_body_imu.isIdentity(0.0); }
};

/// Sun direction in the site frame: fixed, or azimuth/elevation over time.
struct SunConfig {
  Vec3d direction_site = Vec3d(-1.0, 1.0, 1.0).normalized();  ///< K §4.1
  /// Optional table rows (t_s, azimuth_rad, elevation_rad); azimuth from +x towards +y.
  std::vector<Vec3d> azimuth_elevation;
  /// Unit sun vector in the site frame at time t (linear interpolation of the table).
  Vec3d directionAt(double t) const;
};

/// Slip-constraint noise per component (K-17's n_i): defined by the rover layer.
using SlipNoiseConfig = rover::SlipNoise;

/// Process-model parameters (K-1, K-2, K-8, K-9).
struct ProcessConfig {
  double contact_angle_time_constant_s = 2.0;        ///< A_ξ = −1/τ (K-8)
  double contact_angle_noise_rad_per_sqrt_s = 0.05;  ///< n_ξ density
  /// n_c ≤ n_ξ: density of the contact angles' common mode, the normalised sum Σξ_i/√N (so the
  /// wheels' mean ξ̄ has density n_c/√N), same τ. Absent: n_ξ (every wheel independent). The
  /// common mode is the ground's slope under the rover relative to the body, which the body's
  /// own attitude takes up for a rover resting on its wheels; left at n_ξ it trades freely
  /// against vertical velocity where nothing measures that (docs/model.md "Common contact-angle
  /// mode"). Q_ξ = n_ξ² I + (n_c² − n_ξ²)/N · 1 1ᵀ.
  std::optional<double> common_contact_angle_noise_rad_per_sqrt_s;
  double commonContactAngleNoise() const {
    return common_contact_angle_noise_rad_per_sqrt_s.value_or(contact_angle_noise_rad_per_sqrt_s);
  }
  double velocity_time_constant_s = 1.0;          ///< A_v = −1/τ (K-1)
  double velocity_noise_mps2_per_sqrt_hz = 0.05;  ///< n_v density
  double rate_time_constant_s = 1.0;              ///< A_ω = −1/τ (K-2)
  double rate_noise_rad_s2_per_sqrt_hz = 0.05;    ///< n_ω density
};

struct JointSensorConfig {
  double angle_noise_rad = 0.001;            ///< suspension potentiometers (γ) 1σ
  std::optional<double> steering_noise_rad;  ///< steering λ 1σ; default: angle_noise_rad
  double wheel_noise_rad = 0.0005;  ///< drive encoders ψ 1σ (with quantisation q: ≥ q/√12)
  double steeringNoise() const { return steering_noise_rad.value_or(angle_noise_rad); }
  int rate_filter_half_window = 3;  ///< see rover/joint_rates.h
  /// Steering angles change slowly (the rover steers, then drives): they are smoothed over
  /// ±window/2 so that their noise does not bias the slip constraint (E[cos δλ] < 1).
  double steering_filter_window_s = 1.0;
  /// Suspension rates (γ̇) are fitted over a window of this duration (at least
  /// 2·rate_filter_half_window + 1 samples). A suspension angle enters the slip rows twice, in
  /// the wheel frames and through the rate; with a fit only a few samples wide, the neighbours'
  /// rates carry this sample's angle noise, which the estimators then take as signal: a bias
  /// that grows with the joint rate (docs/model.md, joint data). 0.3 s keeps h = 3 at 10 and 20 Hz
  /// and gives h = 8 at 50 Hz.
  double suspension_filter_window_s = 0.3;
};

/// Position-only truth (gps.csv): where its antenna sits on the body.
struct GpsConfig {
  Vec3d antenna_body_m = Vec3d::Zero();  ///< body origin → antenna phase centre, body frame
};

/// Smoother settings a log may carry (rover.yaml `smoother:`; command-line options override).
/// Skid steering by the instantaneous centres of rotation (ICR) of the left and right wheel
/// sets (Mandow et al. 2007): a side's wheels roll at r ψ̇ = v_x − ω_z y_ICR of that side, so a
/// wheel at body y has the nominal longitudinal slip ω_z (y_ICR − y). The ICRs' x is
/// turn_centre_x_m. Without this section y_ICR is each wheel's own y (no such slip).
///
/// Where the ICRs lie depends on the ground (Mandow et al. measure them move by tens of per
/// cent between surfaces), so the estimators carry the error of their half-track as a state δ:
/// y_ICR,L = icr_y_left_m + δ, y_ICR,R = icr_y_right_m − δ, a random walk from N(0, σ²). An ICR
/// error is a yaw-rate error of every wheel at once, proportional to the turn — were it left
/// in the slip rows' white noise, the rows would pull the yaw away from the gyro in every turn.
struct SkidSteerConfig {
  double icr_y_left_m = 0.0;   ///< > 0 (body y, left)
  double icr_y_right_m = 0.0;  ///< < 0
  /// σ of δ (m) at the start of a log; unset: 20 % of the half-track (icr_y_left − icr_y_right)/2.
  /// 0: the ICRs are exact (no state).
  std::optional<double> icr_half_track_sigma_m;
  /// Random-walk density of δ (m/√s): how fast the ground may move the ICRs.
  double icr_half_track_random_walk_m_per_sqrt_s = 0.001;
  double icrHalfTrackSigma() const {
    return icr_half_track_sigma_m.value_or(0.2 * 0.5 * (icr_y_left_m - icr_y_right_m));
  }
};

/// Odometry calibration (`traverse calibrate` fits it): the effective rolling radius of the
/// wheels on each side is the URDF's radius times this scale (a wheel on the body's centre line
/// takes the mean of the two). Applied where the URDF is read (io::parseRoverGeometry), so dead
/// reckoning, EKF, smoother and simulator all see the same radii.
struct OdometryConfig {
  double wheel_radius_scale_left = 1.0;   ///< wheels at body y > 0 (zero joint angles)
  double wheel_radius_scale_right = 1.0;  ///< wheels at body y < 0
  /// How far the effective rolling radius on the ground of this traverse may be from the radius
  /// above (a fraction, 1σ): a random constant per log, common to both sides
  /// (`wheel_radius_scale_sigma`: tyre load and wear, sinkage, the ground's give) plus each
  /// side's own (`wheel_radius_scale_side_sigma`). Without an absolute reference of speed no
  /// estimator can see it, so none estimates it: it is a consider parameter whose variance every
  /// estimator's position covariance carries (est::addOdometryScaleCovariance). 0 (default):
  /// the radii are exact.
  double wheel_radius_scale_sigma = 0.0;
  double wheel_radius_scale_side_sigma = 0.0;
  /// How well the IMU's axes are known against the wheels' rolling direction (rad, 1σ per body
  /// axis): a constant misalignment δ turns every velocity the wheels give by δ before the
  /// IMU's attitude carries it into the site frame (a pitch offset makes height from distance).
  /// A consider parameter like the scale (est::addMountingCovariance); 0 (default): exact.
  double imu_mounting_sigma_rad = 0.0;
  bool hasScaleUncertainty() const {
    return wheel_radius_scale_sigma > 0.0 || wheel_radius_scale_side_sigma > 0.0;
  }
  /// Variance of the scale of the rover's mean wheel speed when a fraction `left` of its wheels
  /// is on the left: σ_c² + σ_s² (ℓ² + (1 − ℓ)²) (σ_c² + σ_s²/2 for a symmetric rover).
  double meanScaleVariance(double left) const {
    return wheel_radius_scale_sigma * wheel_radius_scale_sigma +
           wheel_radius_scale_side_sigma * wheel_radius_scale_side_sigma *
               (left * left + (1.0 - left) * (1.0 - left));
  }
  bool isDefault() const {
    return wheel_radius_scale_left == 1.0 && wheel_radius_scale_right == 1.0 &&
           !hasScaleUncertainty() && imu_mounting_sigma_rad == 0.0;
  }
};

struct SmootherConfig {
  std::optional<std::string> loss;   ///< robust loss on sun and slip: huber, cauchy, none
  std::optional<double> loss_scale;  ///< in standard deviations
};

struct RoverConfig {
  int format = 1;
  std::string name = "rover";
  std::string urdf_file = "rover.urdf";
  /// joints.csv column → URDF joint name, in the file's order, which is the joints.csv column
  /// order. Empty: every movable, non-mimic URDF joint is a column named after it, in the
  /// URDF's document order (io/rover_description.h).
  std::vector<std::pair<std::string, std::string>> joint_names;
  std::optional<double> turn_centre_x_m;  ///< default: mean x of the unsteered wheels
  std::optional<SkidSteerConfig> skid_steer;
  /// Whether the estimators carry the ICRs' half-track error δ (skid steering with σ > 0).
  bool estimatesIcr() const { return skid_steer && skid_steer->icrHalfTrackSigma() > 0; }
  OdometryConfig odometry;
  double gravity_mps2 = 9.80665;
  GyroConfig gyro;
  ImuConfig imu;
  SunSensorConfig sun_sensor;
  AccelConfig accel;
  SunConfig sun;
  SlipNoiseConfig slip_noise;
  ProcessConfig process;
  JointSensorConfig joints;
  SmootherConfig smoother;
  GpsConfig gps;
};

/// Reads and validates rover.yaml (errors: InputError naming file and key).
RoverConfig loadRoverConfig(const std::filesystem::path& yaml_file);
/// rover.yaml with an overlay applied (`traverse run --calibration FILE`, the file
/// `traverse calibrate` writes): the overlay is a rover.yaml of its own (`format: 1`, any subset
/// of the keys) whose keys replace the base file's — mappings merge key by key, anything else
/// (numbers, lists) is replaced whole. The overlay is validated on its own first, so an error in
/// it names the overlay's file and line. An empty `overlay` path: the base file alone.
RoverConfig loadRoverConfig(const std::filesystem::path& yaml_file,
                            const std::filesystem::path& overlay);
/// Same, from rover.yaml text in memory (`file` names it in errors).
RoverConfig parseRoverConfig(const std::string& yaml_text, const std::string& file);
/// Writes a rover.yaml that loadRoverConfig reads back to the same values.
void saveRoverConfig(const std::filesystem::path& yaml_file, const RoverConfig& config);

}  // namespace traverse::io
