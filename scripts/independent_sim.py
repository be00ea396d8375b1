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
  steering) --wheel-noise-rad --gyro-noise --{gyro,accel,joints,sun,cmd,truth}-hz.
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
closed form at each stream's own time stamps.

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
  positive for a rotation about the wheel's +y (contact point moving behind the bottom).
  On a plane every xi is 0 here, so the sign does not show in these logs.
- truth position is the body origin (URDF base_link); the first row is at --start (default 0).
- cmd.csv is the planned body twist, which here equals the true twist (no dynamics).
- K-15's asin(rho) holds only with the sun above the sensor's x-y plane; the off-boresight angle
  is taken as atan2(rho, s_z) (equal there); field_of_view_rad is the full cone angle.
- sun.azimuth_elevation is refused: the contract defines neither the azimuth's origin nor sense.
- turn in place: the ICR is at (turn_centre_x_m, 0) (the key gives only the line's x).
"""
import argparse
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
            xis.append(math.atan2(-dw[0], -dw[2]))
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
    slip = None
    if a.slip_sigma > 0:
        slip = make_slip(segs, rover, a.slip_sigma, a.slip_tau, np.random.default_rng([a.seed, 2]), t_end)
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
    J = np.zeros((len(tj), len(rover.columns)))
    for k, c in enumerate(rover.susp_cols):
        J[:, c] = sol["susp"][k] + r.normal(0, nang, len(tj))
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
        write_csv(out("cmd.csv"), ["t", "vx", "vy", "vz", "wx", "wy", "wz"],
                  [tc] + [clean(sc_["v_b"][:, i]) for i in range(3)] + [clean(sc_["w_b"][:, i]) for i in range(3)],
                  ["%.5f"] + ["%.6g"] * 6)

    # truth
    tt = t0 + np.arange(0.0, t_end, 1.0 / rates["truth"])   # truth spans every stream
    tt = np.append(tt, t0 + t_end) if t0 + t_end - tt[-1] > 1e-6 else tt
    st = state(tt)
    qs = np.array([quat_from_matrix(R) for R in st["R"]])
    for i in range(1, len(qs)):                      # continuous sign
        if qs[i] @ qs[i - 1] < 0:
            qs[i] = -qs[i]
    bt = np.stack([np.interp(tt, tg, bias[:, i]) for i in range(3)], axis=1)
    W = len(rover.wheel_joint)
    cols = [tt] + [st["pos"][:, i] for i in range(3)] + [qs[:, i] for i in range(4)]
    cols += [clean(np.full(len(tt), sol["xi"][w])) for w in range(W)]
    cols += [bt[:, i] for i in range(3)] + [clean(st["v_b"][:, i]) for i in range(3)]
    cols += [clean(st["w_b"][:, i]) for i in range(3)]
    hdr = ["t", "x", "y", "z", "qw", "qx", "qy", "qz"] + [f"xi{w + 1}" for w in range(W)] + \
          ["bx", "by", "bz", "vx", "vy", "vz", "wx", "wy", "wz"]
    fm = ["%.5f"] + ["%.6f"] * 3 + ["%.9f"] * 4 + ["%.6g"] * W + ["%.4e"] * 3 + ["%.6g"] * 6
    write_csv(out("truth.csv"), hdr, cols, fm)

    dist = sum(np.sum(np.linalg.norm(np.diff(state(np.linspace(sg["t0"], sg["t1"], 400) + t0)["pos"], axis=0), axis=1))
               for sg in segs if sg["kind"] != "rest")
    size = sum(os.path.getsize(out(f)) for f in os.listdir(a.out))
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
