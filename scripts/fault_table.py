#!/usr/bin/python3
"""Accuracy and consistency of DR, the EKF and the smoother with and without each simulator fault
(issue 15; docs/simulator.md "Faults", docs/results.md "Fault injection (issue 15)").

For the clean scenario and each fault: `traverse bench accuracy` over seeds 1..RUNS (JSON in
OUT/<scenario>/<case>.json), and `traverse simulate --seed 1` + `traverse run` whose every
output file is searched for NaN/inf. Prints a Markdown table (also OUT/<scenario>/table.md):
per case and estimator the median over seeds of the final position error, position RMSE, yaw
RMSE, mean position NEES, position RMSE/σ; the mean NEES against 3x the clean mean; whether any
number was NaN or inf (any run's trajectory in the bench, `nonfinite_values`, or any file of the
seed-1 run).

    python3 scripts/fault_table.py                      # straight-1m, 20 seeds
    python3 scripts/fault_table.py --scenario multi-stop --runs 20 --jobs 2

Run from anywhere after building the release preset (TRAVERSE= overrides the binary).
"""
import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Faults per scenario, placed where the rover moves. straight-1m: rest 0-5 s, 1 m at 5 cm/s
# cruising from 7 to 25 s, rest from ~27 s. multi-stop: the first leg (4.5 m) moves from 12 to
# ~59 s, rests of 12 s between legs, 781 s in all.
CASES = {
    "straight-1m": [
        ("clean", []),
        ("gap gyro 3 s", ["faults.gap.gyro=[12,3]"]),
        ("gap joints 3 s", ["faults.gap.joints=[12,3]"]),
        ("gap sun 15 s", ["faults.gap.sun=[8,15]"]),
        ("gap accel 3 s", ["faults.gap.accel=[12,3]"]),
        ("gyro spikes 10 x 0.5 rad/s", ["faults.gyro_spikes.count=10",
                                        "faults.gyro_spikes.magnitude_rad_s=0.5"]),
        ("sun dropout 50 %", ["faults.sun_dropout.fraction=0.5"]),
        ("sun outliers 10 x 0.5 rad", ["faults.sun_outliers.count=10",
                                       "faults.sun_outliers.angle_rad=0.5"]),
        ("stuck wheel 2, 6 s", ["faults.stuck_wheel.wheel=2", "faults.stuck_wheel.window=[12,6]"]),
        ("slip burst 5 s", ["faults.slip_burst.window=[12,5]",
                            "faults.slip_burst.longitudinal_mps=-0.02",
                            "faults.slip_burst.lateral_mps=0.005"]),
        ("clock sun +0.3 s", ["faults.clock_offset.sun=0.3"]),
        ("clock joints +0.2 s", ["faults.clock_offset.joints=0.2"]),
        ("clock gyro +0.3 s", ["faults.clock_offset.gyro=0.3"]),
        ("clock accel +0.3 s", ["faults.clock_offset.accel=0.3"]),
        ("no accel", ["faults.no_accel=true"]),
    ],
    "multi-stop": [
        ("clean", []),
        ("gap gyro 5 s", ["faults.gap.gyro=[30,5]"]),
        ("gap joints 5 s", ["faults.gap.joints=[30,5]"]),
        ("gap sun 60 s", ["faults.gap.sun=[20,60]"]),
        ("gap accel 5 s", ["faults.gap.accel=[30,5]"]),
        ("gyro spikes 20 x 0.5 rad/s", ["faults.gyro_spikes.count=20",
                                        "faults.gyro_spikes.magnitude_rad_s=0.5"]),
        ("sun dropout 50 %", ["faults.sun_dropout.fraction=0.5"]),
        ("sun outliers 20 x 0.5 rad", ["faults.sun_outliers.count=20",
                                       "faults.sun_outliers.angle_rad=0.5"]),
        ("stuck wheel 2, 10 s", ["faults.stuck_wheel.wheel=2",
                                 "faults.stuck_wheel.window=[30,10]"]),
        ("slip burst 5 s", ["faults.slip_burst.window=[30,5]",
                            "faults.slip_burst.longitudinal_mps=-0.02",
                            "faults.slip_burst.lateral_mps=0.005"]),
        ("clock sun +0.3 s", ["faults.clock_offset.sun=0.3"]),
        ("clock joints +0.2 s", ["faults.clock_offset.joints=0.2"]),
        ("clock gyro +0.3 s", ["faults.clock_offset.gyro=0.3"]),
        ("clock gyro +5 s", ["faults.clock_offset.gyro=5"]),
        ("clock accel +0.3 s", ["faults.clock_offset.accel=0.3"]),
        ("no accel", ["faults.no_accel=true"]),
    ],
}

COLUMNS = [("final_position_error_m", "final pos. err (m)", "%.4f"),
           ("position_rmse_m", "pos. RMSE (m)", "%.4f"),
           ("yaw_rmse_deg", "yaw RMSE (°)", "%.3f"),
           ("nees_position_mean", "NEES pos. (median)", "%.2f"),
           ("position_rmse_over_sigma", "pos. RMSE/σ", "%.2f")]
ESTIMATORS = ["dr", "ekf", "smoother"]
NONFINITE = re.compile(rb"(?i)(?<![a-z])(nan|-?inf(inity)?)(?![a-z])")
JSON_NULL = re.compile(rb"\bnull\b")  # metrics.json writes a NaN metric as null


def slug(name):
    return re.sub(r"[^a-z0-9]+", "-", name.lower()).strip("-")


def bench(binary, scenario, runs, jobs, sets, json_path):
    cmd = [binary, "--quiet", "bench", "accuracy", "--scenario", scenario, "--runs", str(runs),
           "--json", json_path, "-j", str(jobs)]
    for s in sets:
        cmd += ["--set", s]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        return None, r.stderr.strip().splitlines()[-1:] or ["exit %d" % r.returncode]
    with open(json_path) as f:
        return json.load(f), []


def files_with_nonfinite(binary, scenario, sets, work):
    """simulate --seed 1 + run; the files (log and outputs) holding NaN or inf, and an error."""
    shutil.rmtree(work, ignore_errors=True)
    log, out = os.path.join(work, "log"), os.path.join(work, "out")
    sim = [binary, "--quiet", "simulate", scenario, "-o", log, "--seed", "1"]
    for s in sets:
        sim += ["--set", s]
    r = subprocess.run(sim, capture_output=True, text=True)
    if r.returncode != 0:
        return [], "simulate: " + r.stderr.strip()
    r = subprocess.run([binary, "--quiet", "run", log, "-o", out], capture_output=True, text=True)
    error = "" if r.returncode == 0 else "run exit %d: %s" % (r.returncode, r.stderr.strip()[-200:])
    bad = []
    for d in (log, out):
        for name in sorted(os.listdir(d)) if os.path.isdir(d) else []:
            with open(os.path.join(d, name), "rb") as f:
                text = f.read()
                if NONFINITE.search(text) or (name.endswith(".json") and JSON_NULL.search(text)):
                    bad.append(os.path.relpath(os.path.join(d, name), work))
    return bad, error


MISSING = object()


def stat(report, est, key, what="median"):
    """The statistic; None when it is NaN (JSON null), MISSING when the estimator lacks the key."""
    s = report["estimators"].get(est, {}).get(key) if report else None
    return MISSING if s is None else s.get(what)


def fmt(v, f):
    if v is MISSING:
        return "-"
    if v is None:
        return "NaN"
    return f % v


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", default="straight-1m", choices=sorted(CASES))
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--jobs", type=int, default=2, help="parallel runs inside the one bench process")
    ap.add_argument("--out", default=os.path.join(ROOT, "results", "faults"))
    ap.add_argument("--only", help="run only cases whose name contains this")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a scenario override added to every case (e.g. rover=DIR, a rover.yaml "
                         "variant)")
    ap.add_argument("--no-bench", action="store_true",
                    help="reuse OUT's bench JSON files (the seed-1 NaN check is redone)")
    args = ap.parse_args()
    binary = os.environ.get("TRAVERSE", os.path.join(ROOT, "build", "release", "traverse"))
    out = os.path.join(args.out, args.scenario)
    os.makedirs(out, exist_ok=True)
    cases = [(n, sets + args.set) for n, sets in CASES[args.scenario]
             if not args.only or args.only in n or n == "clean"]

    results = []
    t0 = time.time()
    for name, sets in cases:
        t = time.time()
        json_path = os.path.join(out, slug(name) + ".json")
        if args.no_bench:
            with open(json_path) as f:
                report, errors = json.load(f), []
        else:
            report, errors = bench(binary, args.scenario, args.runs, args.jobs, sets, json_path)
        bad_files, run_error = files_with_nonfinite(binary, args.scenario, sets,
                                                    os.path.join(out, "seed1-" + slug(name)))
        results.append((name, sets, report, errors, bad_files, run_error))
        print("%-30s %6.1f s%s" % (name, time.time() - t,
                                   ("  bench failed: " + " ".join(errors)) if errors else ""),
              file=sys.stderr, flush=True)
    elapsed = time.time() - t0

    clean = results[0][2]
    lines = ["Scenario `%s`, seeds 1..%d, `python3 scripts/fault_table.py --scenario %s --runs %d`"
             "%s. Medians over the seeds; NEES (3 dof, ideal 3): median, and the mean against "
             "3x the clean mean, in brackets (✗ = above); NaN: any non-finite number in any run's trajectory "
             "(`nonfinite_values`) or in any file of `simulate --seed 1` + `run`."
             % (args.scenario, args.runs, args.scenario, args.runs,
                "" if args.no_bench else " (%.0f s)" % elapsed), "",
             "| fault | estimator | " + " | ".join(c[1] for c in COLUMNS) +
             " | NEES mean (clean ×3) | NaN |",
             "|---|---|" + "---|" * len(COLUMNS) + "---|---|"]
    flags = []
    for name, sets, report, errors, bad_files, run_error in results:
        for est in ESTIMATORS:
            if report and est not in report["estimators"]:
                continue
            cells = [fmt(stat(report, est, k), f) for k, _, f in COLUMNS]
            nees, nees_clean = stat(report, est, "nees_position_mean", "mean"), \
                stat(clean, est, "nees_position_mean", "mean")
            ok_clean = nees_clean not in (None, MISSING)
            if nees is MISSING and nees_clean is MISSING:
                consistency = "-"
            elif nees in (None, MISSING) or not ok_clean or nees > 3 * nees_clean:
                consistency = "%s (%s) ✗" % (fmt(nees, "%.2f"),
                                             fmt(3 * nees_clean if ok_clean else nees_clean, "%.2f"))
                flags.append("%s: %s NEES mean %s > 3x clean %s" % (name, est, fmt(nees, "%.2f"),
                                                                    fmt(nees_clean, "%.2f")))
            else:
                consistency = "%s (%s)" % (fmt(nees, "%.2f"), fmt(3 * nees_clean, "%.2f"))
            nonfinite = stat(report, est, "nonfinite_values", "max")
            nan = report is None or nonfinite in (None, MISSING) or nonfinite > 0 or any(
                stat(report, est, k) is None for k, _, _ in COLUMNS)
            if nan:
                flags.append("%s: %s non-finite (max nonfinite_values %s)" % (name, est, nonfinite))
            lines.append("| %s | %s | %s | %s | %s |" % (name if est == "dr" else "", est, " | ".join(cells),
                                                         consistency, "**yes**" if nan else "no"))
        if bad_files:
            flags.append("%s: NaN/inf in %s (seed 1)" % (name, ", ".join(bad_files)))
        if run_error:
            flags.append("%s: %s (seed 1)" % (name, run_error))
        if errors:
            flags.append("%s: bench failed: %s" % (name, " ".join(errors)))
    lines.append("")
    lines.append("Cases, as `--set` keys:")
    lines.append("")
    for name, sets, *_ in results:
        lines.append("- %s: %s" % (name, " ".join("`%s`" % s for s in sets) or "(none)"))
    lines.append("")
    lines.append("Findings: " + ("none" if not flags else ""))
    for f in flags:
        lines.append("- " + f)
    text = "\n".join(lines) + "\n"
    with open(os.path.join(out, "table.md"), "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
