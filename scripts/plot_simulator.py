#!/usr/bin/python3
"""Pictures for docs/simulator.md, from simulator output.

Usage (from the repository root, after building):
    build/release/traverse simulate straight-1m -o /tmp/straight-1m
    /usr/bin/python3 scripts/plot_simulator.py /tmp/straight-1m docs/images
Needs Debian's python3-matplotlib (apt-get install python3-matplotlib).

The terrain background evaluates K-22 as docs/simulator.md reads it (the same formula as
src/sim/terrain.cpp); everything else is read from the log.
"""
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def k22(x, y):
    g = lambda a, k, cx, cy: a * math.exp(-k * ((x - cx) ** 2 + (y - cy) ** 2))
    return 0.2 * (g(0.25, 5 * 6.25, 0.5, 0.2) - g(0.25, 4 * 6.25, 0.5, -0.2) + 0.5 * math.sin(0.75 * x * y))


def read(path):
    with open(path) as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    head = rows[0]
    return {h: [float(r[i]) for r in rows[1:]] for i, h in enumerate(head)}


def main(log, out):
    os.makedirs(out, exist_ok=True)
    truth, joints = read(os.path.join(log, "truth.csv")), read(os.path.join(log, "joints.csv"))

    fig, ax = plt.subplots(figsize=(7, 4.2))
    xs = [-0.4 + 1.9 * i / 190 for i in range(191)]
    ys = [-0.6 + 1.2 * j / 120 for j in range(121)]
    z = [[k22(x, y) for x in xs] for y in ys]
    cs = ax.contourf(xs, ys, z, levels=24, cmap="terrain")
    fig.colorbar(cs, ax=ax, label="terrain height z (m)")
    ax.plot(truth["x"], truth["y"], "k-", lw=2, label="body origin (truth)")
    for side, y in (("left wheels", 0.24), ("right wheels", -0.24)):
        ax.plot([truth["x"][0] - 0.2, truth["x"][-1] + 0.25], [y, y], "--", lw=1, label=side)
    ax.set_xlabel("x (m)"), ax.set_ylabel("y (m)"), ax.set_aspect("equal")
    ax.set_title("K-22 undulating terrain and the straight-1m path")
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout(), fig.savefig(os.path.join(out, "straight-1m-terrain.png"), dpi=110)

    fig, ax = plt.subplots(figsize=(7, 3.2))
    for name, label in (("gamma0", "γ0 differential"), ("gamma1", "γ1 left bogie"), ("gamma2", "γ2 right bogie")):
        ax.plot(joints["t"], [math.degrees(v) for v in joints[name]], label=label)
    ax.set_xlabel("t (s)"), ax.set_ylabel("angle (deg)"), ax.grid(alpha=0.3), ax.legend(fontsize=8)
    ax.set_title("straight-1m: suspension joint angles (joints.csv)")
    fig.tight_layout(), fig.savefig(os.path.join(out, "straight-1m-joints.png"), dpi=110)

    fig, ax = plt.subplots(figsize=(7, 3.2))
    for i in range(1, 7):
        ax.plot(truth["t"], [math.degrees(v) for v in truth["xi%d" % i]], label="ξ%d" % i)
    ax.set_xlabel("t (s)"), ax.set_ylabel("contact angle (deg)"), ax.grid(alpha=0.3), ax.legend(fontsize=8, ncol=3)
    ax.set_title("straight-1m: contact angles ξ1..ξ6 (truth.csv)")
    fig.tight_layout(), fig.savefig(os.path.join(out, "straight-1m-contact.png"), dpi=110)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else "docs/images")
