#!/usr/bin/env python3
"""Issue 15's measured dirty-telemetry cases, made from the bundled logs and run with traverse.

    python3 scripts/dirty_cases.py [OUTDIR] [--traverse build/release/traverse]

Writes OUTDIR/<case>/ (the dirty log) and OUTDIR/<case>.out/ (traverse run's outputs), and prints
each case's warnings and headline metrics (docs/results.md, "Dirty telemetry"). Standard library
only.
"""
import argparse
import pathlib
import shutil
import subprocess

ROOT = pathlib.Path(__file__).resolve().parent.parent
LOGS = ROOT / "datasets" / "logs"


def edit(path, row_fn):
    rows = path.read_text().splitlines()
    out = [rows[0]]
    for r in rows[1:]:
        v = row_fn(r.split(","))
        if v is not None:
            out.append(",".join(v))
    path.write_text("\n".join(out) + "\n")


def drop(t0, t1):
    return lambda r: None if t0 < float(r[0]) < t1 else r


def spike_mid(path):
    rows = path.read_text().splitlines()
    k = 1 + (len(rows) - 1) // 2
    r = rows[k].split(",")
    r[-1] = repr(float(r[-1]) + 2.0)
    rows[k] = ",".join(r)
    path.write_text("\n".join(rows) + "\n")


def shift(dt):
    return lambda r: [repr(float(r[0]) + dt)] + r[1:]


def invalid(r):
    return r[:-1] + ["0"]


CASES = [
    # name, base log, file, edit
    ("straight-1m-gyro-gap", "straight-1m", "gyro.csv", lambda p: edit(p, drop(5.0, 20.0))),
    ("multi-stop-gyro-spike", "multi-stop", "gyro.csv", spike_mid),
    ("multi-stop-joints-gap", "multi-stop", "joints.csv", lambda p: edit(p, drop(85.0, 100.0))),
    ("straight-1m-sun-shifted", "straight-1m", "sun.csv", lambda p: edit(p, shift(1000.0))),
    ("straight-1m-sun-invalid", "straight-1m", "sun.csv", lambda p: edit(p, invalid)),
    ("straight-1m-accel-gap", "straight-1m", "accel.csv", lambda p: edit(p, drop(8.0, 14.0))),
]

KEYS = ("distance_error_pct", "final_position_error_m", "position_rmse_m", "yaw_rmse_deg",
        "position_rmse_over_sigma", "nees_position_mean")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir", nargs="?", default="out/dirty")
    ap.add_argument("--traverse", default=str(ROOT / "build" / "release" / "traverse"))
    a = ap.parse_args()
    out = pathlib.Path(a.outdir)
    out.mkdir(parents=True, exist_ok=True)
    for name, base, file, fn in CASES:
        d = out / name
        shutil.rmtree(d, ignore_errors=True)
        shutil.copytree(LOGS / base, d)
        fn(d / file)
        p = subprocess.run([a.traverse, "run", str(d), "-o", str(out / (name + ".out"))],
                           capture_output=True, text=True)
        print(f"== {name}: exit {p.returncode}")
        for line in p.stderr.splitlines():
            print("  " + line)
        for line in p.stdout.splitlines():
            if line.split(" ")[0] in KEYS or line.startswith("metric"):
                print("  " + line)


if __name__ == "__main__":
    main()
