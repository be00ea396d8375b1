#!/usr/bin/python3
"""Independent telemetry generator for traverse (python3 + numpy only).

Written from the log contract and the papers alone, without reading traverse's own simulator,
so that its logs test the estimators against a second, independent reading of the contract.

Usage (from the repository root):
  /usr/bin/python3 scripts/independent_sim.py --rover datasets/rovers/rocky7 \
      --scenario tilted-multi --seed 1 --out /tmp/indep/multi-1 [--no-cmd] [options]
  /usr/bin/python3 scripts/independent_sim.py --check /tmp/indep/multi-1   # re-read, sanity-check
Scenarios: tilted-multi, tilted-slow, tilted-long, tilted-turns (see SCENARIOS below).
Options: --slope-deg 5 --slope-azimuth-deg 60 --initial-heading-deg 20 --start X Y Z --t0 0
  --profile trapezoid|slow-onset --slip-sigma 0 --slip-tau 5 --joint-noise-rad (suspension and
  steering) --wheel-noise-rad --gyro-noise --{gyro,accel,joints,sun,cmd,truth}-hz
  --terrain plane|undulating (default plane) --terrain-amplitude 0.05 --terrain-components 3
  --terrain-wavelengths 1 4 --terrain-step 0.01 --path-point body|ground (undulating only).
Rates: gyro, accel, joints 50 Hz, sun 5, cmd 20, truth 10 (tilted-long: 20/20/20/2/10/5;
  tilted-slow and tilted-turns: cmd 10, truth 5, to stay under 3 MB); each stream starts at a
  seeded phase in [0, half an interval) after --t0. Rests: 10 s first, 6-10 s (seeded) between
  legs, 8 s last. The same --seed gives the same files.

Model. A rocker-bogie rover (geometry from the log's rover.urdf) drives on a plane tilted by
--slope-deg; the uphill direction has azimuth --slope-azimuth-deg (from site +x towards +y).
The suspension angles are solved by Gauss-Newton so that all wheels touch the plane (for
Rocky-7 the solution is the zero configuration: the URDF puts all wheel centres in one plane
parallel to the body x-y plane at zero angles). Each leg is a rigid motion in the plane:
a translation (straight) or a rotation about a fixed instantaneous centre of rotation (ICR) on
the body line x = turn_centre_x_m (Ackermann arc: ICR at lateral offset R; turn in place:
ICR at y = 0). The front steering joints point their wheels perpendicular to the line to the
ICR; they are moved (2 s, cosine) while the rover stands still, in the middle of a rest.
Wheel drive angles integrate the contact point's speed along the wheel heading / radius
(optionally times 1 + a Gauss-Markov per-wheel slip fraction). Everything is evaluated in
closed form at each stream's own time stamps. Without --terrain (or with --terrain plane) the
output is byte for byte what this script wrote before --terrain existed.

Undulating terrain (--terrain undulating; rovers with 3 + (suspension joints) = (wheels), e.g.
Rocky-7: 6 wheels, rocker + 2 bogies; a rigid rover such as datasets/rovers/pathfinder cannot
keep four wheels on such ground and is refused). The ground is z = h(x, y) in the site frame:
    h = c0 + tan(slope) ((x - x0) cos(az) + (y - y0) sin(az))
           + sum_{k=1..n} A_k sin(kx_k (x - x0) + ky_k (y - y0) + phase_k)
with slope = --slope-deg, az = --slope-azimuth-deg (the tilted plane, 0 for none), (x0, y0) the
--start position, n = --terrain-components (3), wavelength 2 pi / |k_k| uniform in
--terrain-wavelengths (1..4 m), direction and phase uniform in [0, 2 pi), A_k = amplitude * w_k /
sum(w), w_k uniform in [0.5, 1], amplitude = --terrain-amplitude (0.05 m: |h - plane| <= 5 cm),
all drawn from the seed (its own stream: the other streams do not change), and c0 such that the
first body z is --start's z. The terrain's curvature must stay below half the wheel's (one
contact per wheel). The numbers are written to terrain.json in the log (read by --check only).
The plan's (x, y, yaw) are the body origin's site x, y and the heading (Z-Y-X yaw, from site +x;
--initial-heading-deg from site +x); the plan is a horizontal one (lengths and turns are
horizontal). With the body origin held on the plan, a change of roll swings the wheels sideways
(body height x roll change: 15-20 mm on a 5 deg roll change), so they scrub laterally;
--path-point ground puts the plan's x, y on the point the plane's body height below the body
origin along body -z (near the wheels' contact line) instead, which scrubs far less. At every instant of a fine grid (--terrain-step, 0.01 s) Newton's method with a
numerical Jacobian (warm-started from the previous instant's solution: the grid is solved in
time order, in blocks of 25 instants started from the last solution of the block before) solves
body z, roll, pitch and the suspension angles (Rocky-7: rocker gamma0, with the right rocker
the URDF's mimic -1 x gamma0, and bogies gamma1, gamma2) so that every wheel's rim circle (URDF
radius, in the wheel's x-z plane, thin wheel) touches the ground: on each rim the contact angle
xi is where the circle is tangent to the surface (inner Newton on dg/dxi = 0, g = vertical gap
X_z - h(X_x, X_y) of the rim point X(xi) = c + r (sin xi x_w - cos xi z_w)), and that minimum
gap must be 0 (converged to < 1e-11 m; any gap > 1e-6 m stops the script). Truth and joints
are solved exactly at their own stamps (warm start from the grid); the other streams use the
grid linearly interpolated. Velocity, acceleration (incl. vertical), body rate
(Log(R(t-h)^T R(t+h))/2h) and its derivative are central differences on the grid; gyro,
accelerometer (with lever arm) and sun sensor follow the 3-D attitude and motion as on the
plane. Drive angles: rolling without slip at the contact: the point fixed in the non-spinning
wheel frame that is at the contact has velocity v_p (grid differences) and psi_dot = v_p . (d x
a) / r (d: centre -> contact, a: axle, r the rolling radius), times 1 + the slip fraction with
--slip-sigma; integrated on the grid, cubic Hermite at the joint stamps. So r dpsi + r dxi
follows each contact's 3-D path on the ground. Joint-angle noise (--joint-noise-rad or
rover.yaml) is added to the moving rocker, bogie and steering angles. cmd.csv is the plan's
twist (planar velocity in the heading frame, yaw rate), not the true body twist (the contract:
"a prior on the motion"). The steering is moved at rest as on the plane; on curved ground that
moves the body slightly (a steered wheel's lowest point changes), which the truth carries.
--check on such a log adds: every wheel's gap to the ground along the normal from the truth
pose and joints.csv through the forward kinematics (< 1 mm), the suspension angles solved from
the truth pose against joints.csv (the joint noise), the attitude integrated from the gyro
(minus the truth bias; truth rate on axes it lacks) against the truth, and on straight legs
r dpsi + r dxi against each contact's 3-D path length.

Conventions taken from the contract (docs/log-format.md; shared/docs/log-format.md):
- "Files": file names, headers and column order exactly as listed; joints.csv columns are `t`
  and the rover.yaml `joints:` map in its order (else the URDF's movable non-mimic joints in
  document order); truth.csv = t,x,y,z,qw,qx,qy,qz,xi1..xiN,bx,by,bz,vx,vy,vz,wx,wy,wz.
- "Files" (rover is what its URDF says): wheel = continuous joint whose link has a cylinder
  (radius = wheel radius, rotation about +y); steering = other movable joint whose axis is within
  30 deg of body vertical at zero angles; suspension = the rest; a `<mimic>` joint follows its
  master (Rocky-7: rocker_right = -1 x rocker_left, the differential gamma0).
- "Conventions": SI units, radians; one clock; each file strictly increasing; site x,y
  horizontal, z up, gravity (0,0,-g); body x forward, y left, z up; q = (qw,qx,qy,qz), Hamilton,
  rotates body vectors into the site frame (xdot = R(q) v). Gyro = body rate + bias + noise;
  a heading gyro (gyro.axes: z) logs only wz (B_g = [0 0 1], K-13). Accelerometer = specific
  force in the body frame, (0,0,+g) level at rest (K-10, lever arm accelerometer.lever_arm_m).
  Sun: s = (2/pi) asin(rho)/rho (sx,sy) of the sun unit vector in the sensor frame (K-15, K-16),
  sensor frame from sun_sensor.mounting_rpy_rad (sensor -> body, Z-Y-X); valid = 1 iff the sun
  is within half the field of view of the sensor boresight (+z). Joints: psi unwrapped,
  cumulative, rolling forward increases it; wheels 1-3 left (1 front steerable), 4-6 right.
- "rover.yaml" table: noise and set-up values and their defaults (gyro noise / bias random walk /
  initial bias sigma, accelerometer noise, sun noise and fov, sun.direction_site, gravity,
  turn_centre_x_m, joint_sensors.angle/steering/wheel noise, imu.mounting_rpy_rad,
  odometry.wheel_radius_scale_left/right applied to the rolling radius).
- "Numbers": printed with fixed decimals (the contract asks only C-locale numbers).
Conventions I had to choose (the contract does not say; see the report):
- truth vx,vy,vz and wx,wy,wz are in the BODY frame (K-1: v is resolved in body coordinates).
- truth bx,by,bz: the gyro bias per body axis; axes a heading gyro lacks are written as 0.
- truth xi_i: the contact point's angle about the wheel axle from the wheel-frame -z (bottom),
  positive when the contact is ahead of the bottom (towards wheel-frame +x), as docs/log-format.md
  now says ("positive when the contact moves forward (climbing a step ahead)"); an earlier
  version of this script took the opposite sign, which never showed (on a plane every xi is 0).
- truth position is the body origin (URDF base_link); the first row is at --start (default 0).
- cmd.csv is the planned body twist, which on the plane equals the true twist (no dynamics).
- K-15's asin(rho) holds only with the sun above the sensor's x-y plane; the off-boresight angle
  is taken as atan2(rho, s_z) (equal there); field_of_view_rad is the full cone angle.
- sun.azimuth_elevation is refused: the contract defines neither the azimuth's origin nor sense.
- turn in place: the ICR is at (turn_centre_x_m, 0) (the key gives only the line's x).
"""
import argparse
import json
import math
import os
import shutil
import sys
import xml.etree.ElementTree as ET

import numpy as np

# ----------------------------------------------------------------------------------- scenarios
# Legs: ("straight", distance_m, speed_mps) | ("arc", radius_m (+left), angle_deg, speed_mps)
#       | ("turn", angle_deg (+ccw), rate_degps)
_MULTI = [("straight", 2.0, 0.08), ("arc", 1.5, 60.0, 0.07), ("turn", -90.0, 5.0),
          ("straight", 2.5, 0.10), ("arc", -2.0, 45.0, 0.06)]
_LONG = [("straight", 3.0, 0.10), ("arc", 2.0, 40.0, 0.08), ("straight", 2.5, 0.09),
         ("turn", 75.0, 5.0), ("straight", 3.0, 0.10), ("arc", -1.5, 60.0, 0.07),
         ("straight", 2.0, 0.08), ("turn", -120.0, 6.0), ("straight", 3.0, 0.10),
         ("arc", 2.5, 30.0, 0.09), ("straight", 2.5, 0.10), ("turn", 45.0, 4.0),
         ("arc", -2.0, 50.0, 0.08), ("straight", 2.0, 0.10)]
_TURNS = [("turn", 90.0, 5.0), ("arc", 1.0, 90.0, 0.06), ("turn", -180.0, 6.0),
          ("arc", -0.8, 90.0, 0.05), ("straight", 0.5, 0.06), ("turn", 360.0, 6.0),
          ("arc", 1.2, 100.0, 0.07)]
SCENARIOS = {
    "tilted-multi": dict(legs=_MULTI, profile="trapezoid"),
    # Slower logs: truth and cmd at lower rates so that the directory stays under 3 MB.
    "tilted-slow": dict(legs=_MULTI, profile="slow-onset", rates=dict(cmd=10.0, truth=5.0)),
    # Long log: lower default rates so that the directory stays under 3 MB.
    "tilted-long": dict(legs=_LONG, profile="trapezoid",
                        rates=dict(gyro=20.0, accel=20.0, joints=20.0, sun=2.0, cmd=10.0,
                                   truth=5.0)),
    "tilted-turns": dict(legs=_TURNS, profile="trapezoid", rates=dict(cmd=10.0, truth=5.0)),
}
TERRAIN_FILE = "terrain.json"     # written with --terrain undulating, read by --check
DEFAULT_RATES = dict(gyro=50.0, accel=50.0, joints=50.0, sun=5.0, cmd=20.0, truth=10.0)


# ----------------------------------------------------------------------------- small helpers
def rot_axis(axis, ang):
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(ang) * K + (1 - math.cos(ang)) * K @ K


def rpy_matrix(rpy):  # URDF / Z-Y-X: R = Rz(yaw) Ry(pitch) Rx(roll)
    r, p, y = rpy
    return rot_axis([0, 0, 1], y) @ rot_axis([0, 1, 0], p) @ rot_axis([1, 0, 0], r)


def quat_from_matrix(R):  # Hamilton (w, x, y, z) of a rotation matrix
    tr = np.trace(R)
    if tr > 0:
        s = 2 * math.sqrt(tr + 1)
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2 * math.sqrt(1 + R[i, i] - R[j, j] - R[k, k])
        q = [0.0] * 4
        q[0] = (R[k, j] - R[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (R[j, i] + R[i, j]) / s
        q[1 + k] = (R[k, i] + R[i, k]) / s
    q = np.array(q)
    return q / np.linalg.norm(q)


def quat_to_matrix(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


# ------------------------------------------------------------------- minimal YAML (rover.yaml)
def _yaml_value(s):
    s = s.strip()
    if s.startswith("["):
        def parse(i):  # returns (list, next index)
            out, tok, i = [], "", i + 1
            while i < len(s):
                c = s[i]
                if c == "[":
                    v, i = parse(i)
                    out.append(v)
                    tok = ""
                elif c in ",]":
                    if tok.strip():
                        out.append(_yaml_value(tok))
                    tok = ""
                    if c == "]":
                        return out, i
                else:
                    tok += c
                i += 1
            raise ValueError("unterminated list: " + s)
        return parse(0)[0]
    try:
        return float(s) if any(ch in s for ch in ".eE") or not s.lstrip("+-").isdigit() else int(s)
    except ValueError:
        return s.strip("'\"")


def read_yaml(path):
    root, stack = {}, [(-1, None)]
    stack[0] = (-1, root)
    for raw in open(path, encoding="utf-8"):
        line = raw.split("#", 1)[0].rstrip()
        if not line.strip():
            continue
        ind = len(line) - len(line.lstrip())
        key, _, val = line.strip().partition(":")
        while stack[-1][0] >= ind:
            stack.pop()
        parent = stack[-1][1]
        if val.strip() == "":
            parent[key] = {}
            stack.append((ind, parent[key]))
        else:
            parent[key] = _yaml_value(val)
    return root


def yget(d, dotted, default):
    for k in dotted.split("."):
        if not isinstance(d, dict) or k not in d:
            return default
        d = d[k]
    return d


# ------------------------------------------------------------------------------ URDF geometry
class Rover:
    def __init__(self, rover_dir, cfg):
        urdf = os.path.join(rover_dir, str(cfg.get("urdf", "rover.urdf")))
        tree = ET.parse(urdf).getroot()
        self.radius_of_link = {}
        for link in tree.findall("link"):
            for cyl in link.iter("cylinder"):
                self.radius_of_link[link.get("name")] = float(cyl.get("radius"))
        self.joints, self.child_joint, order = {}, {}, []
        for j in tree.findall("joint"):
            o = j.find("origin")
            ax = j.find("axis")
            m = j.find("mimic")
            jd = dict(name=j.get("name"), type=j.get("type"), parent=j.find("parent").get("link"),
                      child=j.find("child").get("link"),
                      xyz=np.array([float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()]),
                      rpy=np.array([float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]),
                      axis=np.array([float(v) for v in (ax.get("xyz") if ax is not None else "1 0 0").split()]),
                      mimic=None if m is None else (m.get("joint"), float(m.get("multiplier", 1)),
                                                    float(m.get("offset", 0))))
            self.joints[jd["name"]] = jd
            self.child_joint[jd["child"]] = jd["name"]
            order.append(jd["name"])
        movable = [n for n in order if self.joints[n]["type"] in ("revolute", "continuous")
                   and self.joints[n]["mimic"] is None]
        jmap = cfg.get("joints")
        if isinstance(jmap, dict) and jmap:
            self.columns = list(jmap.keys())
            self.col_joint = [jmap[c] for c in self.columns]
        else:
            self.columns, self.col_joint = movable[:], movable[:]
        missing = set(movable) - set(self.col_joint)
        if missing:
            sys.exit(f"rover: movable joints not in the joints map: {sorted(missing)}")
        # kinds
        self.kind = []
        for jn in self.col_joint:
            jd = self.joints[jn]
            leaf = jd["child"] not in [j["parent"] for j in self.joints.values()]
            if jd["type"] == "continuous" or (leaf and jd["child"] in self.radius_of_link):
                self.kind.append("wheel")
            else:
                R, _ = self.link_pose(jd["parent"], {})
                axb = R @ rpy_matrix(jd["rpy"]) @ jd["axis"]
                axb /= np.linalg.norm(axb)
                self.kind.append("steer" if abs(axb[2]) >= math.cos(math.radians(30)) else "susp")
        self.wheel_cols = [i for i, k in enumerate(self.kind) if k == "wheel"]
        self.steer_cols = [i for i, k in enumerate(self.kind) if k == "steer"]
        self.susp_cols = [i for i, k in enumerate(self.kind) if k == "susp"]
        self.wheel_joint = [self.col_joint[i] for i in self.wheel_cols]
        # steering joint that carries each wheel (or None)
        self.wheel_steer = []
        for jn in self.wheel_joint:
            chain, link = [], self.joints[jn]["parent"]
            while link in self.child_joint:
                chain.append(self.child_joint[link])
                link = self.joints[chain[-1]]["parent"]
            st = [self.col_joint.index(c) for c in chain if c in self.col_joint
                  and self.kind[self.col_joint.index(c)] == "steer"]
            self.wheel_steer.append(st[0] if st else None)
        r_urdf = np.array([self.radius_of_link[self.joints[jn]["child"]] for jn in self.wheel_joint])
        sl = float(yget(cfg, "odometry.wheel_radius_scale_left", 1.0))
        sr = float(yget(cfg, "odometry.wheel_radius_scale_right", 1.0))
        ys = np.array([self.link_pose(self.joints[jn]["child"], {})[1][1] for jn in self.wheel_joint])
        scale = np.where(ys > 1e-9, sl, np.where(ys < -1e-9, sr, 0.5 * (sl + sr)))
        self.r = r_urdf * scale          # rolling radius (contact geometry uses the URDF one)
        self.r_geom = r_urdf

    def joint_value(self, jn, q):
        jd = self.joints[jn]
        if jd["mimic"] is not None:
            master, mul, off = jd["mimic"]
            return mul * self.joint_value(master, q) + off
        return q.get(jn, 0.0)

    def link_pose(self, link, q):
        """Pose (R, p) of a link in base_link; q: joint name -> angle (joints absent are 0,
        mimic joints follow their master; drive angles are never passed)."""
        R, p = np.eye(3), np.zeros(3)
        while link in self.child_joint:
            jd = self.joints[self.child_joint[link]]
            Rj = rpy_matrix(jd["rpy"])
            if jd["type"] in ("revolute", "continuous"):
                Rj = Rj @ rot_axis(jd["axis"], self.joint_value(jd["name"], q))
            R, p = Rj @ R, Rj @ p + jd["xyz"]
            link = jd["parent"]
        return R, p

    def contacts(self, q, n_b):
        """Contact points (body frame) of every wheel on a plane of body-frame normal n_b, and
        each contact's angle xi about the wheel axle (0 = wheel-frame bottom)."""
        pts, xis = [], []
        for w, jn in enumerate(self.wheel_joint):
            jd = self.joints[jn]
            Rp, pp = self.link_pose(jd["parent"], q)
            R = Rp @ rpy_matrix(jd["rpy"])            # wheel frame, drive angle excluded
            c = Rp @ jd["xyz"] + pp                   # wheel centre
            a = R @ np.array([0.0, 1.0, 0.0])         # axle
            d = -n_b + (n_b @ a) * a                  # lowest rim point of the disc along -n
            d /= np.linalg.norm(d)
            pts.append(c + self.r_geom[w] * d)
            dw = R.T @ d
            xis.append(math.atan2(dw[0], -dw[2]))  # 0 at the bottom, + ahead of it
        return np.array(pts), np.array(xis)

    def solve_on_plane(self, steer):
        """Gauss-Newton: body height h, roll, pitch and the suspension angles so that every
        contact point lies on the plane z_A = 0 of the plane-aligned frame A."""
        ns = len(self.susp_cols)
        x = np.zeros(3 + ns)
        x[0] = 0.3

        def resid(x):
            Rt = rot_axis([0, 1, 0], x[2]) @ rot_axis([1, 0, 0], x[1])
            q = {self.col_joint[c]: v for c, v in zip(self.susp_cols, x[3:])}
            q.update({self.col_joint[c]: v for c, v in steer.items()})
            pts, xis = self.contacts(q, Rt.T @ np.array([0, 0, 1.0]))
            return (pts @ Rt.T)[:, 2] + x[0], Rt, q, pts, xis

        for _ in range(50):
            f = resid(x)[0]
            J = np.empty((len(f), len(x)))
            for k in range(len(x)):
                dx = np.zeros_like(x)
                dx[k] = 1e-7
                J[:, k] = (resid(x + dx)[0] - f) / 1e-7
            step = np.linalg.lstsq(J, -f, rcond=None)[0]
            x = x + step
            if np.max(np.abs(step)) < 1e-13:
                break
        f, Rt, q, pts, xis = resid(x)
        if np.max(np.abs(f)) > 1e-9:
            sys.exit(f"rover: no configuration puts every wheel on the plane (residual {np.max(np.abs(f)):.3g} m)")
        return dict(h=x[0], R_tilt=Rt, susp=x[3:], contacts=pts, xi=xis)


# ------------------------------------------------------------------------ undulating terrain
class Terrain:
    """z = h(x, y) in the site frame (see the module docstring, "Undulating terrain"):
    h = c0 + tan(slope) ((x - x0) cos(az) + (y - y0) sin(az))
           + sum_k A_k sin(kx_k (x - x0) + ky_k (y - y0) + phase_k),
    |(kx_k, ky_k)| = 2 pi / wavelength_k; (x0, y0) = --start; c0 puts the first body z at
    --start's z."""

    def __init__(self, d):
        self.d = d
        self.o = np.array(d["origin_xy"], float)
        self.g0 = math.tan(math.radians(d["slope_deg"])) * np.array(
            [math.cos(math.radians(d["slope_azimuth_deg"])), math.sin(math.radians(d["slope_azimuth_deg"]))])
        self.A = np.array(d["amplitudes_m"], float)
        self.k = np.array(d["wave_vectors_rad_per_m"], float).reshape(-1, 2)
        self.ph = np.array(d["phases_rad"], float)
        self.c0 = float(d["offset_m"])

    @staticmethod
    def random(seed, amplitude, n, wl, slope_deg, slope_az_deg, origin_xy):
        rng = np.random.default_rng([seed, 5])       # own stream: the other streams are untouched
        L = rng.uniform(wl[0], wl[1], n)
        dirs = rng.uniform(0.0, 2 * math.pi, n)
        ph = rng.uniform(0.0, 2 * math.pi, n)
        wgt = rng.uniform(0.5, 1.0, n)
        A = amplitude * wgt / wgt.sum()
        k = (2 * math.pi / L)[:, None] * np.column_stack([np.cos(dirs), np.sin(dirs)])
        return Terrain(dict(kind="undulating", slope_deg=slope_deg, slope_azimuth_deg=slope_az_deg,
                            origin_xy=list(map(float, origin_xy)), amplitudes_m=A.tolist(),
                            wavelengths_m=L.tolist(), wave_vectors_rad_per_m=k.tolist(),
                            phases_rad=ph.tolist(), offset_m=0.0))

    def max_curvature(self):
        return float(np.sum(self.A * np.sum(self.k ** 2, axis=1)))

    def _arg(self, x, y):
        return np.multiply.outer(x - self.o[0], self.k[:, 0]) + np.multiply.outer(y - self.o[1], self.k[:, 1]) + self.ph

    def h(self, x, y):
        return self.c0 + self.g0[0] * (x - self.o[0]) + self.g0[1] * (y - self.o[1]) + np.sin(self._arg(x, y)) @ self.A

    def derivs(self, x, y):
        """h, h_x, h_y, h_xx, h_xy, h_yy."""
        th = self._arg(x, y)
        s, c = np.sin(th), np.cos(th)
        kx, ky = self.k[:, 0], self.k[:, 1]
        h = self.c0 + self.g0[0] * (x - self.o[0]) + self.g0[1] * (y - self.o[1]) + s @ self.A
        return (h, self.g0[0] + c @ (self.A * kx), self.g0[1] + c @ (self.A * ky),
                -(s @ (self.A * kx * kx)), -(s @ (self.A * kx * ky)), -(s @ (self.A * ky * ky)))


def _skew(a):
    return np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])


def euler_zyx(yaw, pitch, roll):  # batched R = Rz(yaw) Ry(pitch) Rx(roll)
    cy, sy, cp, sp, cr, sr = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    R = np.empty(np.shape(yaw) + (3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 0, 2] = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    R[..., 1, 0], R[..., 1, 1], R[..., 1, 2] = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
    R[..., 2, 0], R[..., 2, 1], R[..., 2, 2] = -sp, cp * sr, cp * cr
    return R


def so3_log(R):  # batched rotation vector of R (angles well below pi)
    c = np.clip((np.trace(R, axis1=-2, axis2=-1) - 1) / 2, -1, 1)
    ang = np.arccos(c)
    vee = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    small = ang < 1e-6
    fac = np.where(small, 0.5 + ang ** 2 / 12, ang / (2 * np.sin(np.where(small, 1.0, ang))))
    return vee * fac[..., None]


class Kinematics:
    """Batched forward kinematics of every wheel (URDF chain base_link -> wheel joint, drive
    angle excluded) and the wheel-terrain contact solver for --terrain undulating."""

    def __init__(self, rover):
        self.rover = rover
        W, nc = len(rover.wheel_joint), len(rover.columns)
        chains = []
        for jn in rover.wheel_joint:
            ch, link = [jn], rover.joints[jn]["parent"]
            while link in rover.child_joint:
                ch.append(rover.child_joint[link])
                link = rover.joints[ch[-1]]["parent"]
            chains.append(ch[::-1])                   # base first, the wheel's drive joint last
        D = max(len(c) for c in chains)
        self.Rf = np.tile(np.eye(3), (D, W, 1, 1))
        self.xyz = np.zeros((D, W, 3))
        self.K = np.zeros((D, W, 3, 3))
        self.coef = np.zeros((D, W, nc))
        self.off = np.zeros((D, W))
        for w, ch in enumerate(chains):
            pad = D - len(ch)                         # identity levels at the base end
            for l, jn in enumerate(ch):
                L, jd = pad + l, rover.joints[jn]
                self.Rf[L, w] = rpy_matrix(jd["rpy"])
                self.xyz[L, w] = jd["xyz"]
                if jn == rover.wheel_joint[w] or jd["type"] not in ("revolute", "continuous"):
                    continue                          # fixed joint, or the drive angle (excluded)
                ax = jd["axis"] / np.linalg.norm(jd["axis"])
                self.K[L, w] = _skew(ax)
                name, mul, off = jn, 1.0, 0.0         # resolve mimic chains to a column
                while rover.joints[name]["mimic"] is not None:
                    m, mm, oo = rover.joints[name]["mimic"]
                    off += mul * oo
                    mul *= mm
                    name = m
                if name in rover.col_joint:
                    self.coef[L, w, rover.col_joint.index(name)] = mul
                self.off[L, w] = off
        self.K2 = self.K @ self.K
        self.D, self.W, self.nc = D, W, nc
        self.r = rover.r_geom
        self.ns = len(rover.susp_cols)
        self.path_point = np.zeros(3)                 # body-frame point that follows the plan's x, y

    def body_xy(self, xy, R):
        """Body origin's site x, y when the path point is at plan position xy."""
        return xy - np.einsum("nij,j->ni", R, self.path_point)[:, :2]

    def wheel_frames(self, Q):
        """Q (M, ncols) joint coordinates -> wheel centres (M, W, 3) and wheel frames (M, W, 3, 3)
        in the body frame (wheel frame: x forward, y axle, z up; drive angle excluded)."""
        M = Q.shape[0]
        R = np.broadcast_to(np.eye(3), (M, self.W, 3, 3))
        p = np.zeros((M, self.W, 3))
        for L in range(self.D):
            ang = Q @ self.coef[L].T + self.off[L]
            Rot = np.eye(3) + np.sin(ang)[..., None, None] * self.K[L] + (1 - np.cos(ang))[..., None, None] * self.K2[L]
            p = p + np.einsum("mwij,wj->mwi", R, self.xyz[L])
            R = R @ (self.Rf[L] @ Rot)
        return p, R

    def contacts(self, terrain, pos, Rb, Q, iters=6):
        """Contact of every wheel's rim circle with the terrain. pos (M,3), Rb (M,3,3) body pose
        in the site frame; Q (M, ncols). Returns dict: gap (M,W) vertical distance of the circle's
        lowest point above h (0 = touching), ngap (same along the terrain normal), xi (M,W)
        contact angle (0 = wheel-frame bottom, + forward), X contact points (site), c wheel
        centres (site), Rw wheel frames (site), dg stationarity residual."""
        cb, Rwb = self.wheel_frames(Q)
        c = pos[:, None, :] + np.einsum("mij,mwj->mwi", Rb, cb)
        Rw = np.einsum("mij,mwjk->mwik", Rb, Rwb)
        e1, a, e3 = Rw[..., 0], Rw[..., 1], Rw[..., 2]
        r = self.r[None, :]
        # start: the circle's lowest point along the normal of the terrain's tangent plane below c
        _, hx, hy, _, _, _ = terrain.derivs(c[..., 0], c[..., 1])
        n = np.stack([-hx, -hy, np.ones_like(hx)], axis=-1)
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        dd = -n + np.sum(n * a, axis=-1, keepdims=True) * a
        th = np.arctan2(np.sum(dd * e1, axis=-1), -np.sum(dd * e3, axis=-1))
        # Newton on g'(th) = 0, g(th) = X_z(th) - h(X_x, X_y), X = c + r (sin th e1 - cos th e3)
        for _ in range(iters):
            s, co = np.sin(th)[..., None], np.cos(th)[..., None]
            U = s * e1 - co * e3                      # (X - c) / r
            V = co * e1 + s * e3                      # X' / r
            X = c + r[..., None] * U
            h, hx, hy, hxx, hxy, hyy = terrain.derivs(X[..., 0], X[..., 1])
            g1 = V[..., 2] - hx * V[..., 0] - hy * V[..., 1]
            g2 = -U[..., 2] + hx * U[..., 0] + hy * U[..., 1] - r * (hxx * V[..., 0] ** 2 + 2 * hxy * V[..., 0] * V[..., 1] + hyy * V[..., 1] ** 2)
            th = th - g1 / g2
        s, co = np.sin(th)[..., None], np.cos(th)[..., None]
        U = s * e1 - co * e3
        V = co * e1 + s * e3
        X = c + r[..., None] * U
        h, hx, hy, _, _, _ = terrain.derivs(X[..., 0], X[..., 1])
        gap = X[..., 2] - h
        dg = V[..., 2] - hx * V[..., 0] - hy * V[..., 1]
        return dict(gap=gap, ngap=gap / np.sqrt(1 + hx * hx + hy * hy), xi=th, X=X, c=c, Rw=Rw, dg=dg)

    def _resid(self, terrain, x, xy, yaw, steer):
        M = x.shape[0]
        Q = np.zeros((M, self.nc))
        Q[:, self.rover.susp_cols] = x[:, 3:]
        Q[:, self.rover.steer_cols] = steer
        Rb = euler_zyx(yaw, x[:, 2], x[:, 1])
        pos = np.column_stack([self.body_xy(xy, Rb), x[:, 0]])
        return self.contacts(terrain, pos, Rb, Q)

    def solve(self, terrain, xy, yaw, steer, x0, tol=1e-11, fail_tol=1e-6, what=""):
        """Newton (numerical Jacobian) for x = (z, roll, pitch, suspension angles) at each
        instant so that every wheel's circle touches the terrain (gap 0). xy (N,2), yaw (N,),
        steer (N,k), x0 (N, 3+ns) starting points. Returns x (N, 3+ns), the final contacts."""
        N, nx, eps = len(yaw), 3 + self.ns, 1e-7
        x = np.array(x0, float, copy=True)
        act = np.arange(N)
        for it in range(40):
            if act.size == 0:
                break
            xa = x[act]
            Xp = np.repeat(xa[:, None, :], nx + 1, axis=1)
            Xp[:, 1:, :] += eps * np.eye(nx)
            rep = lambda v: np.repeat(v, nx + 1, axis=0)
            f = self._resid(terrain, Xp.reshape(-1, nx), rep(xy[act]), rep(yaw[act]), rep(steer[act]))["gap"]
            f = f.reshape(len(act), nx + 1, self.W)
            F = f[:, 0]
            done = np.max(np.abs(F), axis=1) < tol
            Jt = (f[:, 1:] - f[:, :1]) / eps          # (n, nx, W) = J^T
            J = np.transpose(Jt, (0, 2, 1))
            nd = ~done
            if np.any(nd):
                JT = Jt[nd]
                if nx == self.W:                      # square: Newton
                    step = np.linalg.solve(J[nd], -F[nd])
                else:                                 # not reached (refused earlier): Gauss-Newton
                    step = np.linalg.solve(JT @ J[nd], -np.einsum("nkw,nw->nk", JT, F[nd]))
                x[act[nd]] += step
            act = act[nd]
        res = self._resid(terrain, x, xy, yaw, steer)
        worst = np.max(np.abs(res["gap"]), axis=1)
        if np.max(worst) > fail_tol or not np.all(np.isfinite(worst)) or np.max(np.abs(res["dg"])) > 1e-9:
            i = int(np.nanargmax(worst))
            sys.exit(f"terrain: contact solve failed{what}: instant {i} (x, y, yaw) = "
                     f"({xy[i, 0]:.4f}, {xy[i, 1]:.4f}, {yaw[i]:.4f}): wheel gap {worst[i]:.3g} m > {fail_tol:g} m")
        return x, res

    def solve_suspension(self, terrain, pos, Rb, Q):
        """Suspension angles (least squares over the wheels' gaps along the normal) for given
        body poses and steering angles; Q (M, ncols) holds the start and the steering."""
        Q = np.array(Q, float, copy=True)
        sc, eps = self.rover.susp_cols, 1e-7
        for _ in range(20):
            f = self.contacts(terrain, pos, Rb, Q)["ngap"]
            J = np.empty(f.shape + (len(sc),))
            for k, c in enumerate(sc):
                Qp = Q.copy()
                Qp[:, c] += eps
                J[..., k] = (self.contacts(terrain, pos, Rb, Qp)["ngap"] - f) / eps
            step = np.linalg.solve(np.einsum("mwk,mwl->mkl", J, J), -np.einsum("mwk,mw->mk", J, f))
            Q[:, sc] += step
            if np.max(np.abs(step)) < 1e-12:
                break
        return Q

    def solve_chunked(self, terrain, xy, yaw, steer, x0, chunk=1500, **kw):
        xs, out = [], dict(gap=[], ngap=[], xi=[], X=[], c=[], Rw=[])
        for i in range(0, len(yaw), chunk):
            s = slice(i, i + chunk)
            x, res = self.solve(terrain, xy[s], yaw[s], steer[s], x0[s], **kw)
            xs.append(x)
            for k in out:
                out[k].append(res[k])
        return np.concatenate(xs), {k: np.concatenate(v) for k, v in out.items()}


# -------------------------------------------------------------------------------- the motion
def profile(kind, T, Tr, tau):
    """Normalised speed u in [0,1], its integral U and derivative du, at tau in [0, T]."""
    tau = np.clip(tau, 0.0, T)
    if kind == "slow-onset":          # sin^2 over the whole leg, no cruise
        w = math.pi / T
        return np.sin(w * tau) ** 2, tau / 2 - np.sin(2 * w * tau) / (4 * w), w * np.sin(2 * w * tau)
    u = np.minimum(1.0, np.minimum(tau / Tr, (T - tau) / Tr))
    du = np.where(tau < Tr, 1 / Tr, np.where(tau > T - Tr, -1 / Tr, 0.0))
    U = np.where(tau < Tr, tau ** 2 / (2 * Tr),
                 np.where(tau <= T - Tr, tau - Tr / 2, (T - Tr) - (T - tau) ** 2 / (2 * Tr)))
    return u, U, du


def build_plan(legs, prof, rover, xc, rng, lead_rest, tail_rest, heading0):
    """Segments with closed-form planar motion. Each: t0, t1, kind, and motion parameters."""
    segs, t, P, phi = [], 0.0, np.zeros(2), heading0
    steer_prev = np.zeros(len(rover.steer_cols))
    wheel_xy = rover.plane["contacts_A"][:, :2]
    for li, leg in enumerate(legs + [None]):
        rest = lead_rest if li == 0 else (tail_rest if leg is None else rng.uniform(6.0, 10.0))
        # the motion of this leg, as a rotation rate Omega about body point c (or translation)
        if leg is None:
            mot = dict(kind="rest", c=None)
        elif leg[0] == "straight":
            mot = dict(kind="straight", amount=leg[1], peak=leg[2], c=None)
        else:
            if leg[0] == "arc":
                R, ang, v = leg[1], math.radians(leg[2]) * np.sign(leg[1]), leg[3]
                c, peak = np.array([xc, R]), v / R
            else:
                ang, c, peak = math.radians(leg[1]), np.array([xc, 0.0]), math.radians(leg[2]) * np.sign(leg[1])
            mot = dict(kind="rotate", amount=ang, peak=peak, c=c)
        steer = steer_prev.copy() if leg is None else np.zeros(len(rover.steer_cols))
        if mot.get("c") is not None:
            for k, col in enumerate(rover.steer_cols):
                w = rover.wheel_steer.index(col)
                dx, dy = wheel_xy[w] - mot["c"]
                steer[k] = math.atan2(dx, -dy) if dy < 0 else math.atan2(-dx, dy)
        # rest (steering moves in its middle, over 2 s)
        segs.append(dict(t0=t, t1=t + rest, kind="rest", P0=P.copy(), phi0=phi,
                         steer_from=steer_prev, steer_to=steer, ts=t + rest / 2 - 1.0))
        t += rest
        if leg is None:
            break
        amount, peak = mot["amount"], mot["peak"]
        cruise = amount / peak                      # time at the peak for the same amount
        if prof == "slow-onset":
            T, Tr = 2 * cruise, 0.0
        else:
            Tr = min(2.0, cruise)
            T = cruise + Tr
        seg = dict(t0=t, t1=t + T, kind=mot["kind"], P0=P.copy(), phi0=phi, peak=peak,
                   prof=prof, T=T, Tr=Tr, c=mot["c"], steer=steer, rate=peak)
        # drive rate per unit of peak*u: contact point speed along the wheel heading / radius
        W = len(rover.wheel_joint)
        if mot["kind"] == "straight":
            seg["k"] = np.ones(W) / rover.r
        else:
            seg["k"] = np.zeros(W)
            for w in range(W):
                rel = wheel_xy[w] - mot["c"]
                lam = 0.0 if rover.wheel_steer[w] is None else steer[rover.steer_cols.index(rover.wheel_steer[w])]
                seg["k"][w] = (-rel[1] * math.cos(lam) + rel[0] * math.sin(lam)) / rover.r[w]
        if mot["kind"] == "rotate":
            cs = P + rot2(phi) @ mot["c"]           # the ICR, fixed in the plane
            seg["C"] = cs
            P = cs + rot2(amount) @ (P - cs)
            phi = phi + amount
        else:
            P = P + amount * np.array([math.cos(phi), math.sin(phi)])
        segs.append(seg)
        steer_prev = steer
        t += T
    return segs


def rot2(a):
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


def evaluate(segs, rover, t, slip=None):
    """Planar state at times t: P (n,2), dP, ddP, phi, dphi, ddphi, steer (n,k), psi (n,W)."""
    n, W = len(t), len(rover.wheel_joint)
    P, dP, ddP = np.zeros((n, 2)), np.zeros((n, 2)), np.zeros((n, 2))
    phi, dphi, ddphi = np.zeros(n), np.zeros(n), np.zeros(n)
    steer = np.zeros((n, len(rover.steer_cols)))
    psi = np.zeros((n, W))
    psi0 = np.zeros(W)
    for s in segs:
        m = (t >= s["t0"]) & (t < s["t1"]) if s is not segs[-1] else (t >= s["t0"])
        tau = t[m] - s["t0"]
        if s["kind"] == "rest":
            P[m], phi[m] = s["P0"], s["phi0"]
            a = np.clip((tau - (s["ts"] - s["t0"])) / 2.0, 0, 1)
            blend = 0.5 - 0.5 * np.cos(math.pi * a)
            steer[m] = s["steer_from"] + np.outer(blend, s["steer_to"] - s["steer_from"])
            psi[m] = psi0
            continue
        u, U, du = profile(s["prof"], s["T"], s["Tr"], tau)
        steer[m] = s["steer"]
        if s["kind"] == "straight":
            h = np.array([math.cos(s["phi0"]), math.sin(s["phi0"])])
            P[m] = s["P0"] + np.outer(s["peak"] * U, h)
            dP[m] = np.outer(s["peak"] * u, h)
            ddP[m] = np.outer(s["peak"] * du, h)
            phi[m] = s["phi0"]
        else:                                         # rotation about the fixed ICR C
            ang = s["peak"] * U
            d0 = s["P0"] - s["C"]
            ca, sa = np.cos(ang), np.sin(ang)
            d = np.stack([ca * d0[0] - sa * d0[1], sa * d0[0] + ca * d0[1]], axis=1)
            Jd = np.stack([-d[:, 1], d[:, 0]], axis=1)
            P[m] = s["C"] + d
            dP[m] = (s["peak"] * u)[:, None] * Jd
            ddP[m] = (s["peak"] * du)[:, None] * Jd - ((s["peak"] * u) ** 2)[:, None] * d
            phi[m] = s["phi0"] + ang
            dphi[m], ddphi[m] = s["peak"] * u, s["peak"] * du
        psi[m] = psi0 + np.outer(s["rate"] * U, s["k"])
        psi0 = psi0 + s["rate"] * profile(s["prof"], s["T"], s["Tr"], np.array([s["T"]]))[1][0] * s["k"]
    if slip is not None:
        psi += slip(t)
    return dict(P=P, dP=dP, ddP=ddP, phi=phi, dphi=dphi, ddphi=ddphi, steer=steer, psi=psi)


def make_slip(segs, rover, sigma, tau, rng, t_end):
    """Extra drive angle from a per-wheel Gauss-Markov slip fraction s: psi_dot *= (1 + s)."""
    dt = 0.005
    tg = np.arange(0.0, t_end + 2 * dt, dt)
    W = len(rover.wheel_joint)
    a = math.exp(-dt / tau)
    s = np.zeros((len(tg), W))
    s[0] = rng.normal(0, sigma, W)
    e = rng.normal(0, sigma * math.sqrt(1 - a * a), (len(tg), W))
    for i in range(1, len(tg)):
        s[i] = a * s[i - 1] + e[i]
    rate = np.zeros((len(tg), W))
    for sg in segs:
        if sg["kind"] == "rest":
            continue
        mm = (tg >= sg["t0"]) & (tg < sg["t1"])
        u = profile(sg["prof"], sg["T"], sg["Tr"], tg[mm] - sg["t0"])[0]
        rate[mm] = np.outer(sg["rate"] * u, sg["k"])
    inc = rate * s
    cum = np.vstack([np.zeros(W), np.cumsum(0.5 * (inc[1:] + inc[:-1]) * dt, axis=0)])
    return lambda t: np.stack([np.interp(t, tg, cum[:, w]) for w in range(W)], axis=1)


def make_slip_fraction(sigma, tau, rng, t_end, W):
    """Per-wheel Gauss-Markov longitudinal slip fraction s(t) (undulating terrain: the drive
    rate from rolling without slip is multiplied by 1 + s)."""
    dt = 0.005
    tg = np.arange(0.0, t_end + 2 * dt, dt)
    a = math.exp(-dt / tau)
    s = np.zeros((len(tg), W))
    s[0] = rng.normal(0, sigma, W)
    e = rng.normal(0, sigma * math.sqrt(1 - a * a), (len(tg), W))
    for i in range(1, len(tg)):
        s[i] = a * s[i - 1] + e[i]
    return lambda t: np.stack([np.interp(t, tg, s[:, w]) for w in range(W)], axis=1)


def undulating_motion(a, rover, segs, t_end, t0, start, h_plane, slip_frac):
    """The 3-D motion over the undulating terrain. Returns (state function, terrain, info)."""
    kin = Kinematics(rover)
    if a.path_point == "ground":                      # the point h_plane below the body origin
        kin.path_point = np.array([0.0, 0.0, -h_plane])
    W, nx = kin.W, 3 + kin.ns
    if nx != W:
        sys.exit(f"--terrain undulating: the rover has {W} wheels but only {kin.ns} suspension "
                 f"joints; a rover with 3 + (suspension joints) = (wheels) is needed so that every "
                 f"wheel can touch the terrain (a rigid 4-wheel rover cannot; not supported)")
    terrain = Terrain.random(a.seed, a.terrain_amplitude, a.terrain_components, a.terrain_wavelengths,
                             a.slope_deg, a.slope_azimuth_deg, start[:2])
    if terrain.max_curvature() > 0.5 / np.max(kin.r):
        sys.exit(f"--terrain undulating: terrain curvature up to {terrain.max_curvature():.3g} 1/m is more "
                 f"than half the wheels' {1 / np.max(kin.r):.3g} 1/m (a wheel could touch in two places); "
                 f"lower --terrain-amplitude or raise --terrain-wavelengths")
    h = a.terrain_step
    n = int(math.ceil(t_end / h))
    tf = h * np.arange(-2, n + 3)                     # plan time, padded for the differences
    ev = evaluate(segs, rover, np.clip(tf, 0.0, t_end))
    xy, yaw, steer = start[:2] + ev["P"], ev["phi"], ev["steer"]

    def solve_unique(xy, yaw, steer, x0, what):
        """Solve only where the planar input changes (rests repeat the pose exactly)."""
        inp = np.column_stack([xy, yaw, steer])
        new = np.ones(len(yaw), bool)
        new[1:] = np.any(inp[1:] != inp[:-1], axis=1)
        iu = np.flatnonzero(new)
        x, res = kin.solve_chunked(terrain, xy[iu], yaw[iu], steer[iu], x0[iu], what=what)
        m = np.searchsorted(iu, np.maximum.accumulate(np.where(new, np.arange(len(yaw)), 0)))
        return x[m], {k: v[m] for k, v in res.items()}

    # first instant from a cold start (level, zero suspension), then the terrain's offset c0 so
    # that the first body z is --start's z
    xi0 = np.zeros((1, nx))
    xi0[0, 0] = terrain.h(np.array(xy[0, 0]), np.array(xy[0, 1])) + h_plane
    x_first, _ = kin.solve(terrain, xy[:1], yaw[:1], steer[:1], xi0, what=" (first instant)")
    terrain.c0 = float(start[2] - x_first[0, 0])
    terrain.d["offset_m"] = terrain.c0
    prev = x_first[0] + np.r_[terrain.c0, np.zeros(nx - 1)]
    # fine grid, in time order: each block of instants starts from the solution at the last
    # instant of the block before (warm start from the previous instant)
    inp = np.column_stack([xy, yaw, steer])
    new = np.ones(len(tf), bool)
    new[1:] = np.any(inp[1:] != inp[:-1], axis=1)
    iu = np.flatnonzero(new)
    Xu = np.empty((len(iu), nx))
    res_u = {k: [] for k in ("xi", "X", "c", "Rw", "gap")}
    B = 25
    for b in range(0, len(iu), B):
        sl = iu[b:b + B]
        xb, rb = kin.solve(terrain, xy[sl], yaw[sl], steer[sl], np.tile(prev, (len(sl), 1)),
                           what=f" at t={tf[sl[0]] + t0:.3f} s")
        Xu[b:b + B] = xb
        prev = xb[-1]
        for k in res_u:
            res_u[k].append(rb[k])
    m = np.searchsorted(iu, np.maximum.accumulate(np.where(new, np.arange(len(tf)), 0)))
    Xf = Xu[m]
    rf = {k: np.concatenate(v)[m] for k, v in res_u.items()}
    # derivatives by central differences on the fine grid (ends: rest, zero)
    R = euler_zyx(yaw, Xf[:, 2], Xf[:, 1])
    pos = np.column_stack([kin.body_xy(xy, R), Xf[:, 0]])
    vel, acc, w_b, dw_b = (np.zeros((len(tf), 3)) for _ in range(4))
    vel[1:-1] = (pos[2:] - pos[:-2]) / (2 * h)
    acc[1:-1] = (pos[2:] - 2 * pos[1:-1] + pos[:-2]) / (h * h)
    w_b[1:-1] = so3_log(np.einsum("nji,njk->nik", R[:-2], R[2:])) / (2 * h)
    dw_b[1:-1] = (w_b[2:] - w_b[:-2]) / (2 * h)
    # drive rates: rolling without slip at the contact. The point fixed in the (non-spinning)
    # wheel frame that is at the contact at t has velocity v_p; the rim's own speed there is
    # psi_dot * r along the rolling direction d x a (d: centre -> contact, a: axle), and the
    # material contact point must not move along it: psi_dot = v_p . (d x a) / r.
    c, Rw, X = rf["c"], rf["Rw"], rf["X"]
    loc = np.einsum("nwji,nwj->nwi", Rw[1:-1], X[1:-1] - c[1:-1])
    v_p = (c[2:] + np.einsum("nwij,nwj->nwi", Rw[2:], loc) - c[:-2] - np.einsum("nwij,nwj->nwi", Rw[:-2], loc)) / (2 * h)
    d = (X[1:-1] - c[1:-1]) / kin.r[None, :, None]
    tdir = np.cross(d, Rw[1:-1, :, :, 1])
    psid = np.zeros((len(tf), W))
    psid[1:-1] = np.sum(v_p * tdir, axis=-1) / rover.r[None, :]
    if slip_frac is not None:
        psid *= 1 + slip_frac(np.clip(tf, 0.0, t_end))
    psi = np.vstack([np.zeros(W), np.cumsum(0.5 * (psid[1:] + psid[:-1]) * h, axis=0)])
    psi -= psi[2]                                     # 0 at plan time 0 (tf[2] = 0)

    def state(t, exact=False):
        tau = np.asarray(t, float) - t0
        e = evaluate(segs, rover, np.clip(tau, 0.0, t_end))
        i = np.clip(np.floor((tau - tf[0]) / h).astype(int), 0, len(tf) - 2)
        fr = ((tau - tf[i]) / h)[:, None]
        lin = lambda A: A[i] * (1 - fr.reshape((-1,) + (1,) * (A.ndim - 1))) + A[i + 1] * fr.reshape((-1,) + (1,) * (A.ndim - 1))
        sxy = start[:2] + e["P"]
        x = lin(Xf)
        st = dict(steer=e["steer"], phi=e["phi"])
        if exact:                                     # full solve, warm start from the grid
            x, res = solve_unique(sxy, e["phi"], e["steer"], Xf[i], what=" (stamps)")
            st["xi"], st["gap"] = res["xi"], res["ngap"]
        # drive angles: cubic Hermite from psi and psi_dot on the grid
        f = fr
        h00, h10, h01, h11 = 2 * f ** 3 - 3 * f ** 2 + 1, f ** 3 - 2 * f ** 2 + f, -2 * f ** 3 + 3 * f ** 2, f ** 3 - f ** 2
        st["psi"] = h00 * psi[i] + h10 * h * psid[i] + h01 * psi[i + 1] + h11 * h * psid[i + 1]
        Rt = euler_zyx(e["phi"], x[:, 2], x[:, 1])
        st.update(R=Rt, pos=np.column_stack([kin.body_xy(sxy, Rt), x[:, 0]]), vel=lin(vel), acc=lin(acc), w_b=lin(w_b),
                  dw_b=lin(dw_b), susp=x[:, 3:], euler=x[:, :3])
        st["v_b"] = np.einsum("nji,nj->ni", Rt, st["vel"])
        # commanded (planned) twist: the plan's planar velocity in the heading frame and yaw rate
        cph, sph = np.cos(e["phi"]), np.sin(e["phi"])
        st["cmd_v"] = np.column_stack([cph * e["dP"][:, 0] + sph * e["dP"][:, 1],
                                       -sph * e["dP"][:, 0] + cph * e["dP"][:, 1], np.zeros(len(tau))])
        st["cmd_w"] = np.column_stack([np.zeros(len(tau)), np.zeros(len(tau)), e["dphi"]])
        return st

    info = dict(grid=len(tf), solved=len(iu), susp_range=(Xf[:, 3:].min(axis=0), Xf[:, 3:].max(axis=0)),
                roll_pitch_max=np.max(np.abs(Xf[:, 1:3]), axis=0), xi_max=np.max(np.abs(rf["xi"])),
                gap_max=np.max(np.abs(rf["gap"])))
    return state, terrain, info


# ---------------------------------------------------------------------------------- writing
def clean(x):  # rounding residue (1e-17, -0) printed as 0
    return np.round(x, 12) + 0.0


def write_csv(path, header, cols, fmts):
    arr = np.column_stack(cols)
    np.savetxt(path, arr, fmt=fmts, delimiter=",", header=",".join(header), comments="")


def stamps(rate, t_end, rng, t0):
    dt = 1.0 / rate
    phase = rng.uniform(0.0, 0.5 * dt)
    return t0 + phase + dt * np.arange(int(math.floor((t_end - t0 - phase) / dt)) + 1)


def generate(a):
    sc = SCENARIOS[a.scenario]
    cfg = read_yaml(os.path.join(a.rover, "rover.yaml"))
    if yget(cfg, "sun.azimuth_elevation", None) is not None:
        sys.exit("rover.yaml: sun.azimuth_elevation is not supported (its azimuth origin and "
                 "sense are not defined by the contract); use sun.direction_site")
    rover = Rover(a.rover, cfg)
    g = float(cfg.get("gravity_mps2", 9.80665))
    rates = dict(DEFAULT_RATES)
    rates.update(sc.get("rates", {}))
    for k in rates:
        if getattr(a, k + "_hz") is not None:
            rates[k] = getattr(a, k + "_hz")
    # plane: rises along the horizontal azimuth alpha by slope s
    s, al = math.radians(a.slope_deg), math.radians(a.slope_azimuth_deg)
    R_plane = rot_axis([-math.sin(al), math.cos(al), 0.0], -s)
    sol = rover.solve_on_plane({c: 0.0 for c in rover.steer_cols})
    rover.plane = dict(contacts_A=sol["contacts"] @ sol["R_tilt"].T + [0, 0, sol["h"]])
    xc = float(cfg.get("turn_centre_x_m", np.mean([p[0] for w, p in enumerate(sol["contacts"])
                                                  if rover.wheel_steer[w] is None])))
    rng_plan = np.random.default_rng([a.seed, 1])
    segs = build_plan([tuple(l) for l in sc["legs"]], a.profile or sc["profile"], rover, xc,
                      rng_plan, 10.0, 8.0, math.radians(a.initial_heading_deg))
    # steering must not move any contact point (checked at every steering value used)
    for sg in segs:
        if sg["kind"] != "rest":
            chk = rover.solve_on_plane({c: v for c, v in zip(rover.steer_cols, sg["steer"])})
            if abs(chk["h"] - sol["h"]) > 1e-9 or (chk["susp"].size and np.max(np.abs(chk["susp"] - sol["susp"])) > 1e-9):
                sys.exit("rover: steering moves the suspension on the plane; not supported")
    t_end = segs[-1]["t1"]
    und = a.terrain == "undulating"
    slip = slip_frac = None
    if a.slip_sigma > 0 and not und:
        slip = make_slip(segs, rover, a.slip_sigma, a.slip_tau, np.random.default_rng([a.seed, 2]), t_end)
    elif a.slip_sigma > 0:
        slip_frac = make_slip_fraction(a.slip_sigma, a.slip_tau, np.random.default_rng([a.seed, 2]), t_end,
                                       len(rover.wheel_joint))
    t0 = a.t0
    start = np.array(a.start, float)

    def state(t):  # t on the log clock
        st = evaluate(segs, rover, t - t0, slip)
        n = len(t)
        R_A = np.einsum("ij,njk->nik", R_plane, np.array([rot_axis([0, 0, 1], p) for p in st["phi"]]))
        R = np.einsum("nij,jk->nik", R_A, sol["R_tilt"])
        P3 = np.column_stack([st["P"], np.zeros(n)])
        pos = start + P3 @ R_plane.T
        vel = np.column_stack([st["dP"], np.zeros(n)]) @ R_plane.T
        acc = np.column_stack([st["ddP"], np.zeros(n)]) @ R_plane.T
        w_b = np.outer(st["dphi"], sol["R_tilt"].T @ [0, 0, 1.0])
        dw_b = np.outer(st["ddphi"], sol["R_tilt"].T @ [0, 0, 1.0])
        v_b = np.einsum("nji,nj->ni", R, vel)
        st.update(R=R, pos=pos, vel=vel, acc=acc, w_b=w_b, dw_b=dw_b, v_b=v_b)
        return st

    if und:
        state, terrain, uinfo = undulating_motion(a, rover, segs, t_end, t0, start, sol["h"], slip_frac)
    os.makedirs(a.out, exist_ok=True)
    for f in ("rover.urdf", "rover.yaml"):
        shutil.copyfile(os.path.join(a.rover, f), os.path.join(a.out, f))
    out = lambda f: os.path.join(a.out, f)
    rs = lambda k: np.random.default_rng([a.seed, 10 + k])  # one generator per stream

    # gyro (bias random walk on the gyro's own stamps)
    axes = str(yget(cfg, "gyro.axes", "z"))
    ax_idx = [2] if axes == "z" else [0, 1, 2]
    r = rs(0)
    tg = stamps(rates["gyro"], t0 + t_end, r, t0)
    sb0 = float(yget(cfg, "gyro.initial_bias_sigma_rad_s", 0.005))
    rw = float(yget(cfg, "gyro.bias_random_walk_rad_s_per_sqrt_s", 1e-5))
    ng = a.gyro_noise if a.gyro_noise is not None else float(yget(cfg, "gyro.noise_rad_s", 0.0031))
    bias = np.zeros((len(tg), 3))
    bias[0, ax_idx] = r.normal(0, sb0, len(ax_idx))
    steps = r.normal(0, 1, (len(tg) - 1, len(ax_idx))) * rw * np.sqrt(np.diff(tg))[:, None]
    bias[1:, ax_idx] = bias[0, ax_idx] + np.cumsum(steps, axis=0)
    R_bi = rpy_matrix(yget(cfg, "imu.mounting_rpy_rad", [0, 0, 0]))
    sg_ = state(tg)
    w_imu = sg_["w_b"] @ R_bi                        # (R_bi^T w)
    gy = w_imu + bias + r.normal(0, ng, (len(tg), 3))
    names = ["wx", "wy", "wz"]
    write_csv(out("gyro.csv"), ["t"] + [names[i] for i in ax_idx],
              [tg] + [gy[:, i] for i in ax_idx], ["%.5f"] + ["%.6f"] * len(ax_idx))

    # accelerometer: specific force at the lever arm, body (then IMU) axes
    r = rs(1)
    ta = stamps(rates["accel"], t0 + t_end, r, t0)
    sa = state(ta)
    L = np.array(yget(cfg, "accelerometer.lever_arm_m", [0, 0, 0]), float)
    w, dw = sa["w_b"], sa["dw_b"]
    a_lever_b = np.cross(dw, L) + np.cross(w, np.cross(w, L))
    a_site = sa["acc"] + np.einsum("nij,nj->ni", sa["R"], a_lever_b)
    f_b = np.einsum("nji,nj->ni", sa["R"], a_site + [0, 0, g])
    na = float(yget(cfg, "accelerometer.noise_mps2", 0.01))
    ba = np.full((len(ta), 3), 0.0)                # accelerometer bias (rover.yaml; default 0)
    ba += r.normal(0, float(yget(cfg, "accelerometer.bias_sigma_mps2", 0.0)), 3)
    rwa = float(yget(cfg, "accelerometer.bias_random_walk_mps2_per_sqrt_s", 0.0))
    ba[1:] += np.cumsum(r.normal(0, 1, (len(ta) - 1, 3)) * rwa * np.sqrt(np.diff(ta))[:, None], axis=0)
    f_i = f_b @ R_bi + ba + r.normal(0, na, (len(ta), 3))
    write_csv(out("accel.csv"), ["t", "ax", "ay", "az"], [ta, f_i[:, 0], f_i[:, 1], f_i[:, 2]],
              ["%.5f"] + ["%.5f"] * 3)

    # sun sensor (K-15, K-16)
    r = rs(2)
    ts = stamps(rates["sun"], t0 + t_end, r, t0)
    ss = state(ts)
    sv = np.array(yget(cfg, "sun.direction_site", [-1, 1, 1]), float)
    sv /= np.linalg.norm(sv)
    R_bs = rpy_matrix(yget(cfg, "sun_sensor.mounting_rpy_rad", [0, 0, 0]))
    u_s = np.einsum("nji,j->ni", ss["R"], sv) @ R_bs   # R_bs^T R^T s_v
    rho = np.hypot(u_s[:, 0], u_s[:, 1])
    off = np.arctan2(rho, u_s[:, 2])                   # off-boresight angle
    fac = np.where(rho > 1e-12, (2 / math.pi) * off / np.maximum(rho, 1e-12), 2 / math.pi)
    nsun = float(yget(cfg, "sun_sensor.noise", 0.005))
    s12 = u_s[:, :2] * fac[:, None] + r.normal(0, nsun, (len(ts), 2))
    fov = float(yget(cfg, "sun_sensor.field_of_view_rad", 2.7925268))
    valid = (off <= fov / 2).astype(int)
    s12 = np.clip(s12, -1, 1)
    write_csv(out("sun.csv"), ["t", "s1", "s2", "valid"], [ts, s12[:, 0], s12[:, 1], valid],
              ["%.5f", "%.6f", "%.6f", "%d"])

    # joints
    r = rs(3)
    tj = stamps(rates["joints"], t0 + t_end, r, t0)
    sj = state(tj)
    nang = a.joint_noise_rad if a.joint_noise_rad is not None else float(yget(cfg, "joint_sensors.angle_noise_rad", 0.001))
    nst = a.joint_noise_rad if a.joint_noise_rad is not None else float(yget(cfg, "joint_sensors.steering_noise_rad", nang))
    nwh = a.wheel_noise_rad if a.wheel_noise_rad is not None else float(yget(cfg, "joint_sensors.wheel_noise_rad", 0.0005))
    if und:
        sj = state(tj, exact=True)
    J = np.zeros((len(tj), len(rover.columns)))
    for k, c in enumerate(rover.susp_cols):
        J[:, c] = (sj["susp"][:, k] if und else sol["susp"][k]) + r.normal(0, nang, len(tj))
    for k, c in enumerate(rover.steer_cols):
        J[:, c] = sj["steer"][:, k] + r.normal(0, nst, len(tj))
    for w, c in enumerate(rover.wheel_cols):
        J[:, c] = sj["psi"][:, w] + r.normal(0, nwh, len(tj))
    write_csv(out("joints.csv"), ["t"] + rover.columns, [tj] + [J[:, i] for i in range(J.shape[1])],
              ["%.5f"] + ["%.5f"] * J.shape[1])

    # commanded body twist
    if not a.no_cmd:
        tc = stamps(rates["cmd"], t0 + t_end, rs(4), t0)
        sc_ = state(tc)
        if und:                                      # the plan's twist, not the true one
            sc_["v_b"], sc_["w_b"] = sc_["cmd_v"], sc_["cmd_w"]
        write_csv(out("cmd.csv"), ["t", "vx", "vy", "vz", "wx", "wy", "wz"],
                  [tc] + [clean(sc_["v_b"][:, i]) for i in range(3)] + [clean(sc_["w_b"][:, i]) for i in range(3)],
                  ["%.5f"] + ["%.6g"] * 6)

    # truth
    tt = t0 + np.arange(0.0, t_end, 1.0 / rates["truth"])   # truth spans every stream
    tt = np.append(tt, t0 + t_end) if t0 + t_end - tt[-1] > 1e-6 else tt
    st = state(tt, exact=True) if und else state(tt)
    qs = np.array([quat_from_matrix(R) for R in st["R"]])
    for i in range(1, len(qs)):                      # continuous sign
        if qs[i] @ qs[i - 1] < 0:
            qs[i] = -qs[i]
    bt = np.stack([np.interp(tt, tg, bias[:, i]) for i in range(3)], axis=1)
    W = len(rover.wheel_joint)
    cols = [tt] + [st["pos"][:, i] for i in range(3)] + [qs[:, i] for i in range(4)]
    cols += [clean(st["xi"][:, w] if und else np.full(len(tt), sol["xi"][w])) for w in range(W)]
    cols += [bt[:, i] for i in range(3)] + [clean(st["v_b"][:, i]) for i in range(3)]
    cols += [clean(st["w_b"][:, i]) for i in range(3)]
    hdr = ["t", "x", "y", "z", "qw", "qx", "qy", "qz"] + [f"xi{w + 1}" for w in range(W)] + \
          ["bx", "by", "bz", "vx", "vy", "vz", "wx", "wy", "wz"]
    fm = ["%.5f"] + ["%.6f"] * 3 + ["%.9f"] * 4 + ["%.6g"] * W + ["%.4e"] * 3 + ["%.6g"] * 6
    if und:                                          # more digits: contacts are rechecked to 1 mm
        fm = ["%.5f"] + ["%.9f"] * 3 + ["%.12f"] * 4 + ["%.9g"] * W + ["%.4e"] * 3 + ["%.9g"] * 6
    write_csv(out("truth.csv"), hdr, cols, fm)
    if und:                                          # the terrain, for --check (not a log file)
        with open(out(TERRAIN_FILE), "w") as f:
            json.dump(terrain.d, f, indent=1)

    dist = sum(np.sum(np.linalg.norm(np.diff(state(np.linspace(sg["t0"], sg["t1"], 400) + t0)["pos"], axis=0), axis=1))
               for sg in segs if sg["kind"] != "rest")
    size = sum(os.path.getsize(out(f)) for f in os.listdir(a.out))
    if und:
        print(f"undulating terrain: amplitudes {np.round(terrain.A, 4).tolist()} m, wavelengths "
              f"{np.round(terrain.d['wavelengths_m'], 3).tolist()} m, max curvature {terrain.max_curvature():.3f} 1/m; "
              f"{uinfo['solved']} of {uinfo['grid']} grid instants solved ({a.terrain_step} s), max |gap| "
              f"{max(uinfo['gap_max'], np.max(np.abs(st['gap']))):.1e} m; |roll|,|pitch| max "
              f"{np.round(np.degrees(uinfo['roll_pitch_max']), 2).tolist()} deg; suspension "
              f"{np.round(np.degrees(uinfo['susp_range'][0]), 2).tolist()} .. "
              f"{np.round(np.degrees(uinfo['susp_range'][1]), 2).tolist()} deg; |xi| max "
              f"{math.degrees(uinfo['xi_max']):.2f} deg")
    print(f"{a.out}: {a.scenario} seed {a.seed}: {len(segs) // 2} legs, {t_end:.1f} s, path {dist:.2f} m, "
          f"slope {a.slope_deg} deg, turn centre x {xc:.3f} m, body height {sol['h']:.4f} m, "
          f"suspension {np.round(sol['susp'], 12).tolist()}, {size / 1e6:.2f} MB")


# ------------------------------------------------------------------ --check: read back a log
def read_csv(path):
    with open(path) as f:
        hdr = f.readline().strip().split(",")
    d = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {h: d[:, i] for i, h in enumerate(hdr)}


def check(d):
    cfg = read_yaml(os.path.join(d, "rover.yaml"))
    rover = Rover(d, cfg)
    g = float(cfg.get("gravity_mps2", 9.80665))
    T = read_csv(os.path.join(d, "truth.csv"))
    Gy = read_csv(os.path.join(d, "gyro.csv"))
    A = read_csv(os.path.join(d, "accel.csv"))
    Jn = read_csv(os.path.join(d, "joints.csv"))
    S = read_csv(os.path.join(d, "sun.csv"))
    q = np.column_stack([T["qw"], T["qx"], T["qy"], T["qz"]])
    Rs = np.array([quat_to_matrix(x) for x in q])
    print(f"quaternion norm max |1-|q||: {np.max(np.abs(1 - np.linalg.norm(q, axis=1))):.2e}")
    # 1. integral of the truth velocity (body frame, rotated to site) against the position
    vs = np.einsum("nij,nj->ni", Rs, np.column_stack([T["vx"], T["vy"], T["vz"]]))
    integ = np.vstack([np.zeros(3), np.cumsum(0.5 * (vs[1:] + vs[:-1]) * np.diff(T["t"])[:, None], axis=0)])
    pos = np.column_stack([T["x"], T["y"], T["z"]])
    print(f"|int R v dt - (x - x0)| max: {np.max(np.linalg.norm(integ - (pos - pos[0]), axis=1)) * 1e3:.3f} mm "
          f"over path {np.sum(np.linalg.norm(np.diff(pos, axis=0), axis=1)):.2f} m")
    # truth body rate against the quaternions' own rotation between rows: Log(R_k^T R_k+1)/dt
    dR = np.einsum("nji,njk->nik", Rs[:-1], Rs[1:])
    ang = np.arccos(np.clip((np.trace(dR, axis1=1, axis2=2) - 1) / 2, -1, 1))
    vee = np.column_stack([dR[:, 2, 1] - dR[:, 1, 2], dR[:, 0, 2] - dR[:, 2, 0], dR[:, 1, 0] - dR[:, 0, 1]])
    rot = vee * np.where(ang > 1e-12, ang / (2 * np.sin(np.maximum(ang, 1e-12))), 0.5)[:, None]
    wt = np.column_stack([T["wx"], T["wy"], T["wz"]])
    e = rot / np.diff(T["t"])[:, None] - 0.5 * (wt[1:] + wt[:-1])
    print(f"Log(R_k^T R_k+1)/dt - mean truth body rate: max {np.max(np.abs(e)):.2e} rad/s")
    # 2. gyro minus bias against the truth rate
    ax = [c for c in ("wx", "wy", "wz") if c in Gy]
    for c in ax:
        b = np.interp(Gy["t"], T["t"], T["b" + c[1]])
        wt = np.interp(Gy["t"], T["t"], T[c])
        e = Gy[c] - b - wt
        print(f"gyro {c} - bias - truth: mean {e.mean():+.2e} std {e.std():.2e} "
              f"(declared noise {yget(cfg, 'gyro.noise_rad_s', 0.0031)})")
    # 3. accelerometer at rest against gravity rotated into the body
    wz_t = np.interp(A["t"], T["t"], T["wz"])
    vt = np.interp(A["t"], T["t"], np.hypot(T["vx"], T["vy"]))
    rest = (np.abs(wz_t) < 1e-12) & (vt < 1e-12)
    idx = np.searchsorted(T["t"], A["t"][rest]).clip(0, len(T["t"]) - 1)
    gb = np.einsum("nji,j->ni", Rs[idx], [0, 0, g])
    e = np.column_stack([A["ax"], A["ay"], A["az"]])[rest] - gb
    print(f"accel at rest - R^T (0,0,g): mean {np.round(e.mean(axis=0), 5)} std {np.round(e.std(axis=0), 5)} "
          f"({rest.sum()} samples; tilt from accel {math.degrees(math.acos(min(1, np.mean(A['az'][rest]) / g))):.2f} deg)")
    # 4. dead reckoning from the wheel angles on each straight stretch
    r = rover.r
    psi = np.column_stack([Jn[rover.columns[c]] for c in rover.wheel_cols])
    wz_j = np.interp(Jn["t"], T["t"], T["wz"])
    vj = np.interp(Jn["t"], T["t"], np.hypot(T["vx"], T["vy"]))
    moving = vj > 1e-9
    edges = np.flatnonzero(np.diff(moving.astype(int)))
    for s0, s1 in zip(edges[::2] + 1, edges[1::2]):
        if np.max(np.abs(wz_j[s0:s1 + 1])) > 1e-12:
            continue
        a0, a1 = max(s0 - 10, 0), min(s1 + 10, len(Jn["t"]) - 1)
        dr = np.mean((psi[a1] - psi[a0]) * r)
        p0 = np.array([np.interp(Jn["t"][a0], T["t"], T[k]) for k in "xyz"])
        p1 = np.array([np.interp(Jn["t"][a1], T["t"], T[k]) for k in "xyz"])
        print(f"straight t={Jn['t'][s0]:.1f}..{Jn['t'][s1]:.1f}: wheels {dr:.4f} m, truth {np.linalg.norm(p1 - p0):.4f} m")
    # 5. sun readings against the truth attitude (K-15)
    sv = np.array(yget(cfg, "sun.direction_site", [-1, 1, 1]), float)
    sv /= np.linalg.norm(sv)
    idx = np.searchsorted(T["t"], S["t"]).clip(0, len(T["t"]) - 1)
    qi = np.array([np.interp(S["t"], T["t"], q[:, i]) for i in range(4)]).T
    u = np.array([quat_to_matrix(x / np.linalg.norm(x)).T @ sv for x in qi])
    rho = np.hypot(u[:, 0], u[:, 1])
    pred = u[:, :2] * ((2 / math.pi) * np.arcsin(rho) / rho)[:, None]
    e = np.column_stack([S["s1"], S["s2"]])[S["valid"] > 0] - pred[S["valid"] > 0]
    print(f"sun - K-15(truth): mean {np.round(e.mean(axis=0), 5)} std {np.round(e.std(axis=0), 5)}, "
          f"valid {int(S['valid'].sum())}/{len(S['t'])}")
    if os.path.exists(os.path.join(d, TERRAIN_FILE)):
        check_undulating(d, cfg, rover, T, Gy, Jn, Rs, q)


def check_undulating(d, cfg, rover, T, Gy, Jn, Rs, q):
    """--check for --terrain undulating: contacts, gyro integral, rolling distance."""
    terrain = Terrain(json.load(open(os.path.join(d, TERRAIN_FILE))))
    kin = Kinematics(rover)
    t = T["t"]
    W = kin.W
    pos = np.column_stack([T["x"], T["y"], T["z"]])
    print(f"undulating terrain ({TERRAIN_FILE}): amplitudes {np.round(terrain.A, 4).tolist()} m, "
          f"wavelengths {np.round(terrain.d['wavelengths_m'], 3).tolist()} m, slope {terrain.d['slope_deg']} deg")
    # 6a. every wheel on the terrain: forward kinematics from truth pose + joints.csv angles
    jc = [c for c in rover.susp_cols + rover.steer_cols]
    Jv = np.column_stack([Jn[rover.columns[c]] for c in jc])
    Q_lin = np.zeros((len(t), kin.nc))
    Q_lin[:, jc] = np.column_stack([np.interp(t, Jn["t"], Jv[:, k]) for k in range(len(jc))])
    Q_fit = Q_lin.copy()                              # local linear fit over +-0.1 s (joint noise)
    lo, hi = np.searchsorted(Jn["t"], t - 0.1), np.searchsorted(Jn["t"], t + 0.1, side="right")
    for i in range(len(t)):
        tj = Jn["t"][lo[i]:hi[i]] - t[i]
        if len(tj) >= 3:
            A = np.column_stack([np.ones_like(tj), tj])
            Q_fit[i, jc] = np.linalg.lstsq(A, Jv[lo[i]:hi[i]], rcond=None)[0][0]
    for name, Q in (("joints interpolated", Q_lin), ("joints fitted +-0.1 s", Q_fit)):
        c = kin.contacts(terrain, pos, Rs, Q)
        gmax = np.max(np.abs(c["ngap"]), axis=0)
        ok = "PASS" if np.max(gmax) < 1e-3 else "FAIL"
        print(f"wheel-terrain gap along the normal ({name}), max per wheel [mm]: "
              f"{np.round(gmax * 1e3, 3).tolist()} -> {ok} (< 1 mm)")
        if "xi1" in T:
            xi_t = np.column_stack([T[f"xi{w + 1}"] for w in range(W)])
            print(f"  contact angle recomputed - truth xi: max {np.degrees(np.max(np.abs(c['xi'] - xi_t))):.4f} deg "
                  f"(truth |xi| max {np.degrees(np.max(np.abs(xi_t))):.3f} deg)")
    cfit = kin.contacts(terrain, pos, Rs, Q_fit)
    # 6a'. suspension angles solved from the truth pose alone (least squares over the wheels'
    # contacts, steering from the fit) against joints.csv: the angle noise on moving joints
    if rover.susp_cols:
        Qs = kin.solve_suspension(terrain, pos, Rs, Q_fit)
        gs = Qs[:, rover.susp_cols]
        for k, col in enumerate(rover.susp_cols):
            nm = rover.columns[col]
            e = Jn[nm] - np.interp(Jn["t"], t, gs[:, k])
            inside = (Jn["t"] >= t[0]) & (Jn["t"] <= t[-1])
            print(f"{nm} (joints.csv) - angle solved from the truth pose: mean {e[inside].mean():+.2e} std "
                  f"{e[inside].std():.2e} rad; range of the solved angle {np.degrees(gs[:, k].min()):+.2f} .. "
                  f"{np.degrees(gs[:, k].max()):+.2f} deg")
    # 6b. gyro integral against the truth attitude: integrate R' = R [w]x at the gyro stamps with
    # the gyro's axes (minus the truth bias) and the truth rate on the others
    tg = Gy["t"]
    sel = (tg >= t[0]) & (tg <= t[-1])
    tg = tg[sel]
    wt = np.column_stack([np.interp(tg, t, T[c]) for c in ("wx", "wy", "wz")])
    wm = wt.copy()
    meas = [i for i, c in enumerate(("wx", "wy", "wz")) if c in Gy]
    for i in meas:
        c = ("wx", "wy", "wz")[i]
        wm[:, i] = Gy[c][sel] - np.interp(tg, t, T["b" + c[1]])
    qg = np.array([np.interp(tg, t, q[:, i]) for i in range(4)]).T
    qg /= np.linalg.norm(qg, axis=1, keepdims=True)
    Rg = np.array([quat_to_matrix(x) for x in qg])
    ng = float(yget(cfg, "gyro.noise_rad_s", 0.0031))
    for label, w in (("truth rate", wt), ("gyro - bias", wm)):
        R = Rg[0].copy()
        err = np.zeros(len(tg))
        yerr = np.zeros(len(tg))
        for k in range(1, len(tg)):
            R = R @ rot_axis_vec(0.5 * (w[k] + w[k - 1]) * (tg[k] - tg[k - 1]))
            e = so3_log(Rg[k].T @ R)
            err[k] = np.linalg.norm(e)
            yerr[k] = (Rg[k] @ e)[2]                  # about the site vertical
        extra = ""
        if label != "truth rate":
            exp1 = ng * math.sqrt(np.median(np.diff(tg)) * (tg[-1] - tg[0]))
            extra = f"; gyro white noise alone gives 1-sigma {math.degrees(exp1):.3f} deg per axis at the end"
        print(f"attitude integrated from {label} over {tg[-1] - tg[0]:.0f} s - truth: max {math.degrees(err.max()):.4f} deg, "
              f"final {math.degrees(err[-1]):.4f} deg (heading {math.degrees(yerr[-1]):+.4f} deg){extra}")
    # 6b'. accelerometer while moving against the specific force from the truth's motion
    A = read_csv(os.path.join(d, "accel.csv"))
    g = float(cfg.get("gravity_mps2", 9.80665))
    L = np.array(yget(cfg, "accelerometer.lever_arm_m", [0, 0, 0]), float)
    vs = np.einsum("nij,nj->ni", Rs, np.column_stack([T["vx"], T["vy"], T["vz"]]))
    wb = np.column_stack([T["wx"], T["wy"], T["wz"]])
    acc, dw = np.gradient(vs, t, axis=0), np.gradient(wb, t, axis=0)
    fb = np.einsum("nji,nj->ni", Rs, acc + [0, 0, g]) + np.cross(dw, L) + np.cross(wb, np.cross(wb, L))
    ins = (A["t"] >= t[0]) & (A["t"] <= t[-1])
    mov = ins & (np.interp(A["t"], t, np.linalg.norm(wb, axis=1) + np.linalg.norm(vs, axis=1)) > 1e-6)
    e = np.column_stack([A[c][mov] - np.interp(A["t"][mov], t, fb[:, i]) for i, c in enumerate(("ax", "ay", "az"))])
    print(f"accel while moving - specific force from the truth (R^T (dv/dt + g) + lever arm): mean "
          f"{np.round(e.mean(axis=0), 5)} std {np.round(e.std(axis=0), 5)} ({mov.sum()} samples; "
          f"declared noise {yget(cfg, 'accelerometer.noise_mps2', 0.01)}; |dv/dt| max {np.max(np.linalg.norm(acc, axis=1)):.3f} m/s2)")
    # 6c. rolling distance on straight legs: r dpsi + r dxi against the 3-D ground path of each
    # contact (rolling without slip) and against the planar distance of the body
    yaw = np.arctan2(Rs[:, 1, 0], Rs[:, 0, 0])
    sp = np.linalg.norm(np.column_stack([T["vx"], T["vy"], T["vz"]]), axis=1)
    straight = np.r_[False, (np.abs(np.diff(yaw)) < 1e-9) & (sp[1:] > 1e-6) & (sp[:-1] > 1e-6)]
    edges = np.flatnonzero(np.diff(np.r_[0, straight.astype(int), 0]))
    psi = np.column_stack([Jn[rover.columns[c]] for c in rover.wheel_cols])
    for s0, s1 in zip(edges[::2] - 1, edges[1::2] - 1):
        if t[s1] - t[s0] < 2:
            continue
        dpsi = np.array([np.interp(t[s1], Jn["t"], psi[:, w]) - np.interp(t[s0], Jn["t"], psi[:, w]) for w in range(W)])
        dxi = cfit["xi"][s1] - cfit["xi"][s0]
        ground = np.sum(np.linalg.norm(np.diff(cfit["X"][s0:s1 + 1], axis=1 - 1), axis=2), axis=0)
        roll_d = rover.r * dpsi + kin.r * dxi
        planar = np.linalg.norm(pos[s1, :2] - pos[s0, :2])
        print(f"straight t={t[s0]:.1f}..{t[s1]:.1f}: r dpsi + r dxi - 3-D contact path [mm] "
              f"{np.round((roll_d - ground) * 1e3, 2).tolist()}; mean r dpsi {np.mean(rover.r * dpsi):.4f} m, "
              f"3-D path {np.mean(ground):.4f} m, planar body {planar:.4f} m")


def rot_axis_vec(v):
    a = np.linalg.norm(v)
    return np.eye(3) if a < 1e-300 else rot_axis(v / a, a)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--check", metavar="DIR", help="re-read a generated log and print sanity checks")
    p.add_argument("--rover", help="directory with rover.urdf and rover.yaml")
    p.add_argument("--scenario", choices=sorted(SCENARIOS))
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--out")
    p.add_argument("--no-cmd", action="store_true", help="do not write cmd.csv")
    p.add_argument("--profile", choices=["trapezoid", "slow-onset"], help="override the scenario's")
    p.add_argument("--terrain", choices=["plane", "undulating"], default="plane",
                   help="plane (default): the tilted plane; undulating: sinusoids on it (see Undulating terrain)")
    p.add_argument("--terrain-amplitude", type=float, default=0.05,
                   help="undulating: sum of the sinusoids' amplitudes, m (default 0.05)")
    p.add_argument("--terrain-components", type=int, default=3, help="undulating: number of sinusoids (default 3)")
    p.add_argument("--terrain-wavelengths", type=float, nargs=2, default=[1.0, 4.0], metavar=("MIN", "MAX"),
                   help="undulating: wavelength range, m (default 1 4)")
    p.add_argument("--path-point", choices=["body", "ground"], default="body",
                   help="undulating: the point whose site x, y follow the plan: the body origin (default) "
                        "or the point the plane's body height below it along body -z")
    p.add_argument("--terrain-step", type=float, default=0.01,
                   help="undulating: internal time step of the pose solve and differences, s (default 0.01)")
    p.add_argument("--slope-deg", type=float, default=5.0)
    p.add_argument("--slope-azimuth-deg", type=float, default=60.0,
                   help="azimuth of the uphill direction, from site +x towards +y")
    p.add_argument("--initial-heading-deg", type=float, default=20.0,
                   help="initial heading in the plane (from the plane's x axis)")
    p.add_argument("--start", type=float, nargs=3, default=[0.0, 0.0, 0.0], help="first body position")
    p.add_argument("--t0", type=float, default=0.0, help="log clock at the start")
    p.add_argument("--slip-sigma", type=float, default=0.0, help="per-wheel longitudinal slip fraction 1 sigma")
    p.add_argument("--slip-tau", type=float, default=5.0, help="slip Gauss-Markov time constant (s)")
    p.add_argument("--joint-noise-rad", type=float, help="override suspension and steering noise")
    p.add_argument("--wheel-noise-rad", type=float, help="override drive-angle noise")
    p.add_argument("--gyro-noise", type=float, help="override gyro.noise_rad_s")
    for k in DEFAULT_RATES:
        p.add_argument(f"--{k}-hz", type=float, help=f"{k} rate (default {DEFAULT_RATES[k]:g} Hz)")
    a = p.parse_args()
    if a.check:
        return check(a.check)
    if not (a.rover and a.scenario and a.out):
        p.error("--rover, --scenario and --out are required")
    generate(a)


if __name__ == "__main__":
    main()
