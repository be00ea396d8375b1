#!/usr/bin/env python3
"""Writes the fuzzers' seed corpora, fuzz/corpus/<target>/, from the bundled files.

fuzz_csv: every CSV stream of datasets/logs/*/ and tests/data/bad/*/, cut to its first 50 lines,
behind the selector byte fuzz/fuzz_csv.cpp reads (the stream's spec; the rocky7 geometry for
the simulated logs; --skip-bad-rows for a copy of each). fuzz_rover_yaml and fuzz_urdf: every
distinct rover.yaml and rover.urdf of datasets/rovers/*/, datasets/logs/*/ and tests/data/bad/*/.
Identical files are written once, named by their content's hash. Run from anywhere:
    python3 scripts/make_fuzz_corpus.py
"""
import hashlib
import pathlib
import shutil

ROOT = pathlib.Path(__file__).resolve().parent.parent
OUT = ROOT / "fuzz" / "corpus"
STREAMS = ["gyro.csv", "joints.csv", "sun.csv", "accel.csv", "cmd.csv", "truth.csv", "gps.csv"]
ROCKY7_LOGS = {"multi-stop", "straight-1m"}  # their joints.csv / truth.csv fit rocky7
MAX_LINES = 50


def write(target, data):
    d = OUT / target
    d.mkdir(parents=True, exist_ok=True)
    (d / hashlib.sha1(data).hexdigest()).write_bytes(data)


def log_dirs():
    yield from sorted((ROOT / "datasets" / "logs").iterdir())
    yield from sorted((ROOT / "tests" / "data" / "bad").iterdir())


def main():
    shutil.rmtree(OUT, ignore_errors=True)
    for d in log_dirs():
        if not d.is_dir():
            continue
        rocky7 = d.name in ROCKY7_LOGS or d.parent.name == "bad"  # bad/ is cut from straight-1m
        for f in sorted(d.glob("*.csv")):
            if f.stat().st_size > (1 << 24):
                continue  # the sparse 'grow' cases
            lines = f.read_bytes().splitlines(keepends=True)[:MAX_LINES]
            text = b"".join(lines)
            which = STREAMS.index(f.name) if f.name in STREAMS else 7
            geo = 8 if rocky7 and f.name in ("joints.csv", "truth.csv") else 0
            for skip in (0, 16):
                write("fuzz_csv", bytes([which | geo | skip]) + text)
        for name, target in (("rover.yaml", "fuzz_rover_yaml"), ("rover.urdf", "fuzz_urdf")):
            if (d / name).is_file():
                write(target, (d / name).read_bytes())
    for d in sorted((ROOT / "datasets" / "rovers").iterdir()):
        for name, target in (("rover.yaml", "fuzz_rover_yaml"), ("rover.urdf", "fuzz_urdf")):
            if (d / name).is_file():
                write(target, (d / name).read_bytes())
    for target in sorted(p.name for p in OUT.iterdir()):
        files = list((OUT / target).iterdir())
        print(f"{target}: {len(files)} files, {sum(f.stat().st_size for f in files)} bytes")


if __name__ == "__main__":
    main()
