#!/usr/bin/python3
"""Markdown tables from `traverse bench accuracy --json` files (scripts/run_accuracy.sh)."""
import glob
import json
import os
import sys

KEYS = ["distance_error_pct", "final_position_error_m", "final_error_pct_of_path", "max_cross_track_m",
        "position_rmse_m", "roll_rmse_deg", "pitch_rmse_deg", "yaw_rmse_deg", "contact_angle_rmse_deg",
        "bias_z_error_dps", "ate_posyaw_m", "rpe_pct_per_m", "nees_position_mean", "nees_attitude_mean",
        "position_rmse_over_sigma", "yaw_rmse_over_sigma"]


def fmt(s):
    if s is None or s.get("median") is None:
        return "-"
    return "%.4g (%.3g ± %.2g)" % (s["median"], s["mean"], s["std"] if s["std"] is not None else float("nan"))


def scenario_table(path):
    d = json.load(open(path))
    ests = list(d["estimators"].keys())
    print("\n### %s — %d runs\n" % (d["scenario"], d["runs"]))
    print("| metric | " + " | ".join(ests) + " |")
    print("|---|" + "---|" * len(ests))
    for k in KEYS:
        if any(k in d["estimators"][e] for e in ests):
            print("| %s | %s |" % (k, " | ".join(fmt(d["estimators"][e].get(k)) for e in ests)))


def sweep_table(out):
    files = sorted(glob.glob(os.path.join(out, "planar-18m-sun-ratio-*.json")),
                   key=lambda f: int(f.rsplit("-", 1)[1].split(".")[0]))
    if not files:
        return
    print("\n### planar-18m sun-sensor rate sweep (R §5) — median over runs\n")
    print("| f_others / f_SS | sun rate (Hz) | EKF final position error (m) | EKF yaw RMSE (deg) | DR final position error (m) |")
    print("|---|---|---|---|---|")
    for f in files:
        k = int(f.rsplit("-", 1)[1].split(".")[0])
        e = json.load(open(f))["estimators"]
        print("| %d | %.3g | %.4g | %.4g | %.4g |" % (k, 50.0 / k, e["ekf"]["final_position_error_m"]["median"],
                                                    e["ekf"]["yaw_rmse_deg"]["median"],
                                                    e["dr"]["final_position_error_m"]["median"]))


def main(out):
    for s in ["straight-1m", "turn-in-place-360", "obstacle", "planar-18m", "multi-stop"]:
        p = os.path.join(out, s + ".json")
        if os.path.exists(p):
            scenario_table(p)
    sweep_table(out)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "results/accuracy")
