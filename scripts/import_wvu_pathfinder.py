#!/usr/bin/env python3
"""Import a WVU Pathfinder field run (MATLAB v7.3 .mat = HDF5) into a traverse log directory.

    python3 scripts/import_wvu_pathfinder.py datasets/real/wvu-pathfinder/s5t1.mat \
        datasets/logs/wvu-pathfinder-s5t1

Writes gyro.csv, accel.csv, joints.csv, gps.csv (docs/log-format.md), copies rover.urdf and
rover.yaml from datasets/rovers/pathfinder/, and the source's LICENSE beside a README.md naming
the source file and its sha256. The output is byte for byte the same on every run and machine:
numbers are rounded to fixed decimals (below) and printed with Python's correctly rounded '%f'.
docs/real-logs.md documents every choice; this file is the template for the next real rover.

Frames, signs and units (source: datasets/real/wvu-pathfinder/README.md, checked against the
data by tests/import_wvu_pathfinder_test.py):
  - Time: Unix seconds in the file; t = 0 at the earliest time stamp of the IMU, odometry and
    GPS streams, rounded to 1 us (the source's resolution at 1.6e9 s is 0.24 us).
  - IMU (ADIS16495, 250 Hz) frame: x forward, y right, z down. Body frame: x forward, y left,
    z up. v_body = R_BODY_IMU v_imu with R_BODY_IMU = diag(1, -1, -1) (a roll of pi).
    Gyro rad/s. Accelerometer: specific force in m/s^2; at rest the source reads Az = -9.80 in
    its z-down frame, i.e. the reaction to gravity points up, so body az = +9.80 at rest as the
    log format wants.
  - Wheels (10 Hz): angles in rad from the motor controllers, unwrapped and cumulative; the left
    wheels count negative when driving forward, so psi = WHEEL_SIGN * angle makes rolling
    forward increase psi on both sides. The ...Vel channels are not written: traverse
    differentiates the angles itself.
  - GPS (10 Hz): geodetic fixes (llhGPS, radians and metres above the WGS-84 ellipsoid)
    converted to east/north/up metres about the first fix -- the site frame (x east, y north,
    z up); checked against the authors' own ENUGPS. Per-fix 1-sigma: s5t1 carries the
    receiver's LonSigma (east), LatSigma (north), HeightSigma (up) in metres; test17run carries
    none, so RTK_SIGMA_M (estimated) is used.
  - GPS time: s5t1's fixes carry their own stamps (tTGPS). test17run's sit on the odometry's
    stamps, fix k on odometry sample k, and that clock is wrong: the fixes stop moving 1.1 s
    before the wheels and the accelerometer say the rover stops, and the lag of the GPS course
    behind the gyro's yaw rate grows over the run. For such a file the importer fits the fixes'
    clock, tau = t_1 + offset + rate * (t - t_1), to the wheels' speed profile
    (fit_gps_clock) and writes the fitted stamps; the fit is printed and written in README.md.
"""
import argparse
import hashlib
import os
import shutil
import sys

import h5py
import numpy as np

R_BODY_IMU = np.diag([1.0, -1.0, -1.0])
# joints.csv column (= URDF joint name in datasets/rovers/pathfinder/rover.urdf) -> source
# variable and the sign that makes rolling forward positive.
WHEELS = [
    ("front_left_wheel", "frontLeftPos", -1.0),
    ("rear_left_wheel", "rearLeftPos", -1.0),
    ("front_right_wheel", "frontRightPos", 1.0),
    ("rear_right_wheel", "rearRightPos", 1.0),
]
# Fixed decimals per quantity: each far below the sensor's own resolution or noise.
DECIMALS_T = 6  # 1 us
DECIMALS_GYRO = 7  # 1e-7 rad/s; noise 1e-3 rad/s per sample
DECIMALS_ACCEL = 6  # 1e-6 m/s^2; noise 2e-2 m/s^2 per sample
DECIMALS_WHEEL = 7  # 1e-7 rad; encoder quantum 4.7e-5 rad
DECIMALS_GPS = 4  # 0.1 mm; RTK spread at rest 2 mm
# ESTIMATED 1-sigma (east, north, up) of test17run's RTK fixes: 1 cm RTK noise combined with
# the time-base error of fixes re-stamped to 10 Hz odometry (+-0.05 s uniform at 0.5 m/s:
# 1.4 cm along track); the spread at rest is ~2 mm.
RTK_SIGMA_M = (0.02, 0.02, 0.03)
WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563


# The GPS clock fit's search: rate within +-5 %, offset at the first fix within +-3 s.
CLOCK_RATE_RANGE = (0.95, 1.05)
CLOCK_OFFSET_RANGE_S = (-3.0, 3.0)
# GPS speed over fixes k - h .. k + h: 0.6 s, long enough to average the RTK noise (2 mm per fix).
CLOCK_SPEED_HALF_SPAN = 3


class InputProblem(Exception):
    """Bad input: reported as one line, exit code 2."""


def read_mat(path):
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise InputProblem(f"{path}:0: cannot read as MATLAB v7.3 (HDF5): {e}") from None
    with f:
        def get(name, required=True):
            if name not in f:
                if required:
                    raise InputProblem(f"{path}:0: variable '{name}' missing")
                return None
            return np.array(f[name], dtype=np.float64)

        raw = {k: get(k) for k in ["tTimu", "Gx", "Gy", "Gz", "Ax", "Ay", "Az", "tTodom", "llhGPS"]}
        for _, var, _ in WHEELS:
            raw[var] = get(var)
        raw["ENUGPS"] = get("ENUGPS")
        for k in ["tTGPS", "LatSigma", "LonSigma", "HeightSigma"]:
            raw[k] = get(k, required=False)
    for k, v in raw.items():
        if v is not None and k not in ("llhGPS", "ENUGPS"):
            raw[k] = v.reshape(-1)
    return raw


def enu_from_llh(llh):
    """East/north/up (m) of WGS-84 geodetic fixes (lat, lon rad; h m) about the first fix."""
    lat, lon, h = llh[:, 0], llh[:, 1], llh[:, 2]
    e2 = WGS84_F * (2.0 - WGS84_F)
    n = WGS84_A / np.sqrt(1.0 - e2 * np.sin(lat) ** 2)
    ecef = np.stack([(n + h) * np.cos(lat) * np.cos(lon), (n + h) * np.cos(lat) * np.sin(lon),
                     (n * (1.0 - e2) + h) * np.sin(lat)])
    d = ecef - ecef[:, :1]
    la, lo = lat[0], lon[0]
    r_enu_ecef = np.array([
        [-np.sin(lo), np.cos(lo), 0.0],
        [-np.sin(la) * np.cos(lo), -np.sin(la) * np.sin(lo), np.cos(la)],
        [np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)],
    ])
    return (r_enu_ecef @ d).T


def fit_gps_clock(t_gps, enu, t_odom, psi):
    """The clock of GPS fixes whose stamps are not their own: (offset s, rate, cost, cost at
    the identity). tau_k = t_1 + offset + rate (t_k - t_1) is when fix k was taken, on the clock
    of the odometry (t_odom, wheel angles psi N x W, rolling forward positive). Fitted by
    matching the GPS's horizontal speed over fixes k +- CLOCK_SPEED_HALF_SPAN with the wheels'
    mean rate at tau_k times a free scale (the rolling radius), in the mean absolute
    difference; a grid, then a finer grid about its best. What fixes the clock are the
    speed's changes (starts and stops); a run that never changes speed leaves it unfixed, and
    the cost at the identity is returned beside the best so that the caller can see it."""
    h = CLOCK_SPEED_HALF_SPAN
    v = np.full(len(t_gps), np.nan)
    v[h:-h] = (np.linalg.norm(enu[2 * h:, :2] - enu[:-2 * h, :2], axis=1) /
               (t_gps[2 * h:] - t_gps[:-2 * h]))
    u = np.abs(np.gradient(psi.mean(axis=1), t_odom))

    def costs(offsets, rate):
        tau = t_gps[0] + offsets[:, None] + rate * (t_gps - t_gps[0])[None, :]
        w = np.interp(tau, t_odom, u, left=np.nan, right=np.nan)
        ok = np.isfinite(w) & np.isfinite(v)[None, :]
        w0 = np.where(ok, w, 0.0)
        v0 = np.where(ok, v[None, :], 0.0)
        scale = (w0 * v0).sum(axis=1) / np.maximum((w0 * w0).sum(axis=1), 1e-300)
        return np.abs(v0 - scale[:, None] * w0).sum(axis=1) / np.maximum(ok.sum(axis=1), 1)

    def search(rates, offsets, best):
        for rate in rates:
            c = costs(offsets, rate)
            i = int(np.argmin(c))
            if best is None or c[i] < best[2]:
                best = (float(offsets[i]), float(rate), float(c[i]))
        return best

    best = search(np.arange(CLOCK_RATE_RANGE[0], CLOCK_RATE_RANGE[1] + 1e-9, 1e-3),
                  np.arange(CLOCK_OFFSET_RANGE_S[0], CLOCK_OFFSET_RANGE_S[1] + 1e-9, 0.02), None)
    best = search(best[1] + np.arange(-2e-3, 2e-3 + 1e-9, 1e-4),
                  best[0] + np.arange(-0.05, 0.05 + 1e-9, 2e-3), best)
    identity = float(costs(np.zeros(1), 1.0)[0])
    return best[0], best[1], best[2], identity


def convert(raw, source):
    """The log's streams: name -> (columns, t, values N x C, decimals of the values), and a
    note on the GPS clock (None when the fixes carry their own stamps)."""
    llh = raw["llhGPS"]
    enu = enu_from_llh(llh)
    wheels = np.stack([sign * raw[var] for _, var, sign in WHEELS], axis=1)
    clock = None
    if raw["tTGPS"] is not None:
        t_gps = raw["tTGPS"]
    else:
        t_gps = raw["tTodom"]
        if len(t_gps) != len(enu):
            raise InputProblem(f"{source}:0: {len(t_gps)} GPS times but {len(enu)} fixes")
        offset, rate, cost, identity = fit_gps_clock(t_gps, enu, raw["tTodom"], wheels)
        shift_end = offset + (rate - 1.0) * (t_gps[-1] - t_gps[0])
        t_gps = t_gps[0] + offset + rate * (t_gps - t_gps[0])
        clock = (f"the GPS fixes sit on the odometry's time stamps; their clock, fitted to the "
                 f"wheels' speed profile, is {offset:+.3f} s at the first fix and runs at "
                 f"{rate:.4f} x the odometry's ({shift_end:+.2f} s at the last fix; mean "
                 f"|speed misfit| {cost:.4f} m/s, {identity:.4f} with the stamps as they are)")
    t0 = min(raw["tTimu"][0], raw["tTodom"][0], t_gps[0])

    def times(t):
        out = np.round(t - t0, DECIMALS_T)
        if not np.all(np.diff(out) > 0):
            raise InputProblem(f"{source}:0: time stamps not strictly increasing at 1 us")
        return out

    gyro = (R_BODY_IMU @ np.stack([raw["Gx"], raw["Gy"], raw["Gz"]])).T
    accel = (R_BODY_IMU @ np.stack([raw["Ax"], raw["Ay"], raw["Az"]])).T

    if raw["ENUGPS"].shape == enu.shape and np.abs(raw["ENUGPS"] - enu).max() > 1e-3:
        raise InputProblem(f"{source}:0: llhGPS and ENUGPS disagree by more than 1 mm")
    if raw["LatSigma"] is not None:
        sigma = np.stack([raw["LonSigma"], raw["LatSigma"], raw["HeightSigma"]], axis=1)
    else:
        sigma = np.tile(RTK_SIGMA_M, (len(t_gps), 1))
    if len(t_gps) != len(enu):
        raise InputProblem(f"{source}:0: {len(t_gps)} GPS times but {len(enu)} fixes")
    return {
        "gyro.csv": (["wx", "wy", "wz"], times(raw["tTimu"]), gyro, DECIMALS_GYRO),
        "accel.csv": (["ax", "ay", "az"], times(raw["tTimu"]), accel, DECIMALS_ACCEL),
        "joints.csv": ([c for c, _, _ in WHEELS], times(raw["tTodom"]), wheels, DECIMALS_WHEEL),
        "gps.csv": (["x", "y", "z", "sx", "sy", "sz"], times(t_gps),
                    np.concatenate([enu, sigma], axis=1), DECIMALS_GPS),
    }, clock


def number(x, decimals):
    """x at fixed decimals, trailing zeros dropped, no negative zero."""
    s = "%.*f" % (decimals, x)
    if "." in s:
        s = s.rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def csv_text(columns, t, values, decimals):
    lines = [",".join(["t"] + columns)]
    for k in range(len(t)):
        lines.append(",".join([number(t[k], DECIMALS_T)] +
                              [number(v, decimals) for v in values[k]]))
    return "\n".join(lines) + "\n"


def write_atomically(path, data):
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(data)
    os.replace(tmp, path)


def sha256(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def provenance(source, clock):
    name = os.path.basename(source)
    return (f"# {os.path.splitext(name)[0]}: a WVU Pathfinder field run as a traverse log\n\n"
            f"Written by `scripts/import_wvu_pathfinder.py` from `{name}` (sha256 "
            f"{sha256(source)}), a file of the public repository `wvu-navLab/corenav-GP` (MIT "
            "licence, `LICENSE` here, copyright Cagri Kilic 2020); provenance of the source in "
            "`datasets/real/wvu-pathfinder/README.md`. Frames, signs, units and the choices "
            "made: `docs/real-logs.md`. `gps.csv` is position-only truth (GPS fixes with "
            "per-fix 1-sigma); the rover has no sun sensor and no commanded twist.\n" +
            (f"\nGPS time: {clock}.\n" if clock else ""))


def main(argv):
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("mat", help="source .mat file (s5t1.mat, test17run.mat)")
    parser.add_argument("outdir", help="log directory to write")
    parser.add_argument("--rover", default=os.path.join(here, "..", "datasets", "rovers",
                                                        "pathfinder"),
                        help="directory holding rover.urdf and rover.yaml")
    args = parser.parse_args(argv)
    try:
        if not os.path.isfile(args.mat):
            raise InputProblem(f"{args.mat}:0: file not found")
        for f in ("rover.urdf", "rover.yaml"):
            if not os.path.isfile(os.path.join(args.rover, f)):
                raise InputProblem(f"{os.path.join(args.rover, f)}:0: file not found")
        licence = os.path.join(os.path.dirname(os.path.abspath(args.mat)), "LICENSE")
        if not os.path.isfile(licence):
            raise InputProblem(f"{licence}:0: the source's licence must sit beside it")
        streams, clock = convert(read_mat(args.mat), args.mat)
    except InputProblem as e:
        print(e, file=sys.stderr)
        return 2
    os.makedirs(args.outdir, exist_ok=True)
    for name, (columns, t, values, decimals) in streams.items():
        text = csv_text(columns, t, values, decimals)
        write_atomically(os.path.join(args.outdir, name), text.encode("ascii"))
    for f in ("rover.urdf", "rover.yaml"):
        with open(os.path.join(args.rover, f), "rb") as src:
            write_atomically(os.path.join(args.outdir, f), src.read())
    with open(licence, "rb") as src:
        write_atomically(os.path.join(args.outdir, "LICENSE"), src.read())
    if clock:
        print(f"{args.mat}: {clock}", file=sys.stderr)
    write_atomically(os.path.join(args.outdir, "README.md"),
                     provenance(args.mat, clock).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
