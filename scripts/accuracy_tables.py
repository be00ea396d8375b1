#!/usr/bin/python3
"""The study tables (and plots) of docs/results.md from `traverse bench accuracy` JSON files
(scripts/run_accuracy.sh): the per-scenario tables are results/accuracy/accuracy.md, written by
the bench itself; this prints the sun-rate sweep and the noise-sensitivity tables with DR, EKF,
RTS and the smoother side by side, and draws docs/images/study-*.png when matplotlib exists."""
import glob
import json
import os
import sys

ESTIMATORS = ["dr", "ekf", "rts", "smoother"]
LABELS = {"dr": "DR", "ekf": "EKF", "rts": "RTS", "smoother": "smoother"}


def med(e, est, key):
    s = e.get(est, {}).get(key)
    return None if s is None else s.get("median")


def cell(v):
    return "-" if v is None else "%.4g" % v


def load(pattern, value_of):
    rows = []
    for f in glob.glob(pattern):
        rows.append((value_of(f), json.load(open(f))))
    return sorted(rows, key=lambda r: r[0])


def table(title, xname, rows, keys, xfmt=lambda x: "%g" % x):
    print("\n### %s — median of %d runs\n" % (title, rows[0][1]["runs"] if rows else 0))
    head = "| %s |" % xname
    for key, name in keys:
        for est in ESTIMATORS:
            head += " %s %s |" % (LABELS[est], name)
    print(head)
    print("|---|" + "---|" * (len(keys) * len(ESTIMATORS)))
    for x, d in rows:
        line = "| %s |" % xfmt(x)
        for key, _ in keys:
            for est in ESTIMATORS:
                line += " %s |" % cell(med(d["estimators"], est, key))
        print(line)


def plot(name, xlabel, rows, keys, logx=False):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, axes = plt.subplots(1, len(keys), figsize=(5 * len(keys), 3.6))
    colors = {"dr": "#e67e22", "ekf": "#1f77b4", "rts": "#9467bd", "smoother": "#2ca02c"}
    for ax, (key, label) in zip(axes, keys):
        for est in ESTIMATORS:
            xs = [x for x, d in rows if med(d["estimators"], est, key) is not None]
            ys = [med(d["estimators"], est, key) for x, d in rows if med(d["estimators"], est, key) is not None]
            if ys:
                ax.plot(xs, ys, "o-", color=colors[est], label=LABELS[est])
        ax.set_xlabel(xlabel)
        ax.set_ylabel(label)
        if logx:
            ax.set_xscale("log")
        ax.grid(alpha=0.3)
    axes[0].legend()
    fig.tight_layout()
    path = os.path.join("docs", "images", "study-%s.png" % name)
    fig.savefig(path, dpi=90)
    print("\n(plot: %s)" % path)


def main(out):
    keys = [("final_position_error_m", "final error (m)"), ("yaw_rmse_deg", "yaw RMSE (deg)"),
            ("position_rmse_over_sigma", "pos. RMSE/σ")]
    sweep = load(os.path.join(out, "planar-18m-sun-ratio-*.json"),
                 lambda f: int(f.rsplit("-", 1)[1].split(".")[0]))
    if sweep:
        table("planar-18m sun-sensor rate sweep (R §5), f_others / f_SS", "f_others / f_SS", sweep, keys)
        plot("sun-rate-sweep", "f_others / f_SS (others at 50 Hz)", sweep, keys)
    slip = load(os.path.join(out, "planar-18m-slip-*.json"),
                lambda f: float(os.path.basename(f)[len("planar-18m-slip-"):-5]))
    if slip:
        table("planar-18m sensitivity to white wheel slip (m/s)", "slip σ (m/s)", slip, keys)
        plot("slip-sensitivity", "white wheel slip σ (m/s)", slip, keys, logx=True)
    bias = load(os.path.join(out, "planar-18m-biasrw-*.json"),
                lambda f: float(os.path.basename(f)[len("planar-18m-biasrw-"):-5]))
    if bias:
        table("planar-18m sensitivity to gyro-bias drift (random walk, rad/s/√s)",
              "bias random walk", bias, keys + [("bias_z_error_dps", "bias z error (°/s)")])
        plot("bias-sensitivity", "gyro bias random walk (rad/s/√s; 0 plotted at 1e-6)",
             [(x if x > 0 else 1e-6, d) for x, d in bias], keys, logx=True)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "results/accuracy")
