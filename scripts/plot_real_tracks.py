#!/usr/bin/python3
"""Track plots of the real WVU Pathfinder runs over their GPS (docs/results.md, "Odometry
calibration"): one PNG per run, two panels — uncalibrated, and calibrated on the other run —
each with the GPS fixes and the DR, EKF and smoother tracks.

Usage (from the repository root, after building):
    bash scripts/calibration_crossval.sh out/calibration-crossval
    /usr/bin/python3 scripts/plot_real_tracks.py out/calibration-crossval docs/images
Needs Debian's python3-numpy and python3-matplotlib.

Each track is aligned to the GPS by yaw and translation (least squares over the fixes inside
its span, the antenna lever arm taken as zero as in the bundled rover.yaml) — the 4-DoF
alignment of docs/evaluation.md without its robust weights, so the picture and metrics.json
can differ by the few fixes the evaluation rejects as outliers.
"""
import os
import sys

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

RUNS = {"s5t1": "test17run", "test17run": "s5t1"}
STYLE = {"dr": ("DR", "tab:orange"), "ekf": ("EKF", "tab:blue"), "smoothed": ("smoother", "tab:green")}


def read_csv(path):
    return np.genfromtxt(path, delimiter=",", names=True)


def align(track, gps):
    """Yaw + translation mapping the track's positions onto the GPS at the fix times."""
    t = gps["t"]
    inside = (t >= track["t"][0]) & (t <= track["t"][-1])
    p = np.stack([np.interp(t[inside], track["t"], track[c]) for c in "xyz"], axis=1)
    q = np.stack([gps[c][inside] for c in "xyz"], axis=1)
    pc, qc = p.mean(axis=0), q.mean(axis=0)
    a, b = p[:, :2] - pc[:2], q[:, :2] - qc[:2]
    yaw = np.arctan2(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]), np.sum(a * b))
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    full = np.stack([track[c] for c in "xyz"], axis=1)
    aligned = (full - pc) @ R.T + qc
    err = (p - pc) @ R.T + qc - q
    return aligned, np.sqrt(np.mean(np.sum(err**2, axis=1)))


def main(root, out_dir):
    os.makedirs(out_dir, exist_ok=True)
    for run, other in RUNS.items():
        gps = read_csv(f"datasets/logs/wvu-pathfinder-{run}/gps.csv")
        fig, axes = plt.subplots(1, 2, figsize=(12, 5.5), sharex=True, sharey=True)
        for ax, cal, title in ((axes[0], "none", "uncalibrated"),
                               (axes[1], other, f"calibrated on {other}")):
            ax.plot(gps["x"], gps["y"], ".", color="0.6", ms=2, label="GPS fixes")
            for name, (label, colour) in STYLE.items():
                path = os.path.join(root, f"{run}-{cal}", f"{name}.csv")
                if not os.path.exists(path):
                    continue
                xyz, rms = align(read_csv(path), gps)
                ax.plot(xyz[:, 0], xyz[:, 1], color=colour, lw=1.2, label=f"{label} (RMS {rms:.2f} m)")
            ex, ey = np.ptp(gps["x"]), np.ptp(gps["y"])
            to_scale = max(ex, ey) < 4 * min(ex, ey)  # a straight run: stretch the narrow axis
            ax.set_title(f"{run}: {title}" + ("" if to_scale else " (axes not to scale)"))
            ax.set_xlabel("east (m)")
            if to_scale:
                ax.set_aspect("equal", adjustable="box")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8, loc="best")
        axes[0].set_ylabel("north (m)")
        fig.tight_layout()
        out = os.path.join(out_dir, f"wvu-{run}-tracks.png")
        fig.savefig(out, dpi=90)
        print("wrote", out)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
