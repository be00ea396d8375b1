#!/usr/bin/env python3
"""Two GPS-free checks of a real log's IMU against its wheels (docs/results.md, session 19).

  /usr/bin/python3 scripts/imu_consistency.py LOG OUT

LOG is a traverse log directory (accel.csv, gyro.csv, joints.csv), OUT a `traverse run` output
directory of it (segments.csv; ekf.csv, rts.csv, smoothed.csv).

1. Accelerometer against the wheels. The attitude integrated from the gyro alone (bias from the
   first rest window, roll and pitch from its mean specific force) removes gravity from the
   accelerometer; the forward remainder is compared with the wheels' mean speed (rolling radius
   from --radius) differentiated, the lateral with w_z * v, both box-averaged over a window W,
   while moving (|v| > 0.05 m/s). Printed: the remainders' std per W. A white process of density
   q gives std^2 * W = q^2; the O-4 velocity model assumes q = accelerometer noise * sqrt(period).
2. Tilt at the stops. At every stop of the wheels of at least 1.5 s (0.3 s trimmed at each end)
   the mean specific force gives roll and pitch; printed: each estimator's roll and pitch minus
   those, their RMS, and the EKF's error over its own sigma at the stops after the first.
"""
import argparse
import os

import numpy as np


def read(path):
    return np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding=None)


def expm(v):
    th = np.linalg.norm(v)
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    if th < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + np.sin(th) / th * K + (1 - np.cos(th)) / th**2 * K @ K


def box(t, x, width):
    c = np.cumsum(np.concatenate([[0.0], x]))
    lo, hi = np.searchsorted(t, t - width / 2), np.searchsorted(t, t + width / 2)
    return (c[hi] - c[lo]) / np.maximum(hi - lo, 1)


def roll_pitch(f):
    return np.degrees(np.arctan2(f[1], f[2])), np.degrees(np.arctan2(-f[0], np.hypot(f[1], f[2])))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log")
    ap.add_argument("out")
    ap.add_argument("--radius", type=float, default=0.11, help="wheel radius (m)")
    ap.add_argument("--gravity", type=float, default=9.8006, help="gravity (m/s^2)")
    a = ap.parse_args()
    A, G, J = (read(os.path.join(a.log, f)) for f in ("accel.csv", "gyro.csv", "joints.csv"))
    S = read(os.path.join(a.out, "segments.csv"))
    rests = [(r["t_start"], r["t_end"]) for r in S if r["kind"] == "rest"]
    f = np.vstack([A["ax"], A["ay"], A["az"]]).T
    w = np.vstack([G["wx"], G["wy"], G["wz"]]).T
    tg, ta, tj = G["t"], A["t"], J["t"]
    wheels = np.vstack([J[n] for n in J.dtype.names[1:]]).T
    v = np.gradient(wheels.mean(1) * a.radius, tj)

    # 1. accelerometer against the wheels
    t0, t1 = rests[0]
    f0 = f[(ta > t0 + 0.5) & (ta < t1 - 0.5)].mean(0)
    bias = w[(tg > t0 + 0.5) & (tg < t1 - 0.5)].mean(0)
    roll, pitch = np.arctan2(f0[1], f0[2]), np.arctan2(-f0[0], np.hypot(f0[1], f0[2]))
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    R = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]]) @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    grav = np.empty((len(tg), 3))
    for k in range(len(tg)):
        grav[k] = R.T @ np.array([0, 0, a.gravity])
        if k + 1 < len(tg):
            R = R @ expm((w[k] - bias) * (tg[k + 1] - tg[k]))
    lin = f - np.vstack([np.interp(ta, tg, grav[:, i]) for i in range(3)]).T
    wz = np.interp(tj, tg, w[:, 2])
    moving = np.abs(box(tj, v, 0.5)) > 0.05
    print("accelerometer minus wheels while moving (%d joint samples):" % moving.sum())
    print("| W (s) | forward std (m/s^2) | lateral std (m/s^2) | forward std^2 W (m^2/s^3) |")
    print("|---|---|---|---|")
    for width in (0.5, 2.0, 8.0):
        vs = box(tj, v, width)
        fx = box(tj, np.interp(tj, ta, lin[:, 0]), width) - np.gradient(vs, tj)
        fy = box(tj, np.interp(tj, ta, lin[:, 1]), width) - box(tj, wz, width) * vs
        print("| %g | %.3f | %.3f | %.3f |" % (width, fx[moving].std(), fy[moving].std(), fx[moving].var() * width))

    # 2. tilt at the stops
    still = np.abs(v) < 0.002
    stops, i = [], 0
    while i < len(tj):
        j = i
        while j < len(tj) and still[j]:
            j += 1
        if j > i and tj[j - 1] - tj[i] >= 1.5:
            stops.append((tj[i] + 0.3, tj[j - 1] - 0.3))
        i = max(j, i + 1)
    ests = {k: read(os.path.join(a.out, k + ".csv")) for k in ("ekf", "rts", "smoothed")
            if os.path.exists(os.path.join(a.out, k + ".csv"))}

    def est_roll_pitch(E, t):
        qw, qx, qy, qz = (np.interp(t, E["t"], E[k]) for k in ("qw", "qx", "qy", "qz"))
        return roll_pitch([2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)])

    print("\ntilt at %d stops of >= 1.5 s (estimate minus gravity, deg):" % len(stops))
    errs = {k: [] for k in ests}
    ratio = []
    for n, (s0, s1) in enumerate(stops):
        m = (ta > s0) & (ta < s1)
        r, p = roll_pitch(f[m].mean(0))
        line = "%6.1f-%6.1f s  gravity roll %6.2f pitch %6.2f" % (s0, s1, r, p)
        for k, E in ests.items():
            er, ep = est_roll_pitch(E, (s0 + s1) / 2)
            errs[k].append(np.hypot(er - r, ep - p))
            line += "  %s %+.2f %+.2f" % (k, er - r, ep - p)
            if k == "ekf" and n > 0:
                t = (s0 + s1) / 2
                ratio += [(er - r) / np.degrees(np.interp(t, E["t"], E["sroll"])),
                          (ep - p) / np.degrees(np.interp(t, E["t"], E["spitch"]))]
        print(line)
    for k in errs:
        print("%s: RMS tilt error at the stops %.2f deg" % (k, np.sqrt(np.mean(np.square(errs[k])))))
    if ratio:
        print("ekf: tilt error / sigma at the stops after the first: RMS %.2f, max %.2f (%d values)"
              % (np.sqrt(np.mean(np.square(ratio))), np.max(np.abs(ratio)), len(ratio)))


if __name__ == "__main__":
    main()
