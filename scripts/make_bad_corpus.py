#!/usr/bin/env python3
"""Writes tests/data/bad/: one small log directory per kind of bad (or dirty but usable) input.

Every case starts from the same tiny valid log, the first two seconds of the bundled
straight-1m (rover.yaml, rover.urdf, gyro.csv, joints.csv, sun.csv, truth.csv), and changes one
thing. Each case directory holds `expected.txt` (read by tests/bad_corpus_test.cpp):

    exit N               the exit code of `traverse run CASE -o OUT`
    stderr TEXT          a substring of stderr's first line
    lines N              stderr has exactly N lines (default 1 for exit 2, any for exit 0)
    same-outputs         the outputs equal those of the clean case byte for byte
    env NAME=VALUE       set for the run
    grow FILE BYTES      before the run, the copy's FILE is extended (sparse) to BYTES

Usage: python3 scripts/make_bad_corpus.py [REPO]   (rewrites every case of REPO/tests/data/bad/)
"""
import os
import re
import shutil
import sys

REPO = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..")
SOURCE = os.path.join(REPO, "datasets", "logs", "straight-1m")
OUT = os.path.join(REPO, "tests", "data", "bad")
T_END = 2.0  # seconds kept from the bundled log
STREAMS = ["gyro.csv", "joints.csv", "sun.csv", "truth.csv"]


def read(path):
    with open(path, "rb") as f:
        return f.read().decode()


def trimmed(name):
    lines = read(os.path.join(SOURCE, name)).splitlines(keepends=True)
    return "".join([lines[0]] + [l for l in lines[1:] if float(l.split(",")[0]) <= T_END + 1e-9])


BASE = {name: trimmed(name) for name in STREAMS}
BASE["rover.yaml"] = read(os.path.join(SOURCE, "rover.yaml"))
BASE["rover.urdf"] = read(os.path.join(SOURCE, "rover.urdf"))

CASES = []


def case(name, expected, **changes):
    """changes: file name (with '.' as '_') -> new text, bytes, or None to remove the file."""
    CASES.append((name, expected, {k.replace("_csv", ".csv").replace("_yaml", ".yaml")
                                   .replace("_urdf", ".urdf"): v for k, v in changes.items()}))


def rows(name):
    return BASE[name].splitlines(keepends=True)


def with_row(name, index, text):
    """The file with data row `index` (0 = first after the header) replaced by `text`."""
    r = rows(name)
    r[index + 1] = text + "\n"
    return "".join(r)


def yaml_sub(pattern, repl):
    new, n = re.subn(pattern, repl, BASE["rover.yaml"], count=1, flags=re.M)
    assert n == 1, pattern
    return new


def urdf_sub(pattern, repl):
    new, n = re.subn(pattern, repl, BASE["rover.urdf"], count=1, flags=re.S)
    assert n == 1, pattern
    return new


def drop_column(text, column):
    lines = text.splitlines(keepends=True)
    k = lines[0].rstrip("\n").split(",").index(column)
    out = []
    for l in lines:
        fields = l.rstrip("\n").split(",")
        del fields[k]
        out.append(",".join(fields) + "\n")
    return "".join(out)


# --- bad input: exit 2, one line naming file, line and problem -------------------------------
E = "exit 2\nstderr "
case("missing-gyro", E + "gyro.csv: required file missing", gyro_csv=None)
case("missing-joints", E + "joints.csv: required file missing", joints_csv=None)
case("missing-rover-yaml", E + "rover.yaml: required file missing", rover_yaml=None)
case("missing-urdf", E + "rover.urdf: required file missing", rover_urdf=None)
case("missing-column", E + "joints.csv:1: missing column 'psi6'",
     joints_csv=drop_column(BASE["joints.csv"], "psi6"))
case("extra-column", E + "gyro.csv:1: unknown column 'wq'",
     gyro_csv="".join(l.rstrip("\n") + (",wq\n" if i == 0 else ",0\n")
                      for i, l in enumerate(rows("gyro.csv"))))
case("misnamed-column", E + "sun.csv:1: unknown column 's3'",
     sun_csv=BASE["sun.csv"].replace("t,s1,s2,valid", "t,s1,s3,valid", 1))
case("misordered-columns", E + "sun.csv:1: columns in wrong order",
     sun_csv=BASE["sun.csv"].replace("t,s1,s2,valid", "t,s2,s1,valid", 1))
case("gyro-axes-mismatch", E + "gyro.csv: header has 't,wx,wy,wz' but rover.yaml gyro.axes is 'z'",
     gyro_csv="".join(("t,wx,wy,wz\n" if i == 0 else l.split(",")[0] + ",0,0," + l.split(",")[1])
                      for i, l in enumerate(rows("gyro.csv"))))
case("non-numeric", E + "gyro.csv:6: non-numeric value 'abc' in column 'wz'",
     gyro_csv=with_row("gyro.csv", 4, "0.2,abc"))
case("nan", E + "gyro.csv:6: NaN in column 'wz'", gyro_csv=with_row("gyro.csv", 4, "0.2,nan"))
case("inf", E + "joints.csv:6: infinite value inf in column 'gamma1'",
     joints_csv=with_row("joints.csv", 4, re.sub(r"^([^,]*,[^,]*,)[^,]*", r"\1inf",
                                                 rows("joints.csv")[5].rstrip("\n"))))
case("beyond-double", E + "gyro.csv:6: value '1e999' in column 'wz' is beyond the range of a double",
     gyro_csv=with_row("gyro.csv", 4, "0.2,1e999"))
case("empty-file", E + "gyro.csv:1: empty file: no header line", gyro_csv="")
case("header-only", E + "joints.csv:1: header only, no data rows", joints_csv=rows("joints.csv")[0])
case("non-monotonic-time", E + "gyro.csv:9: non-increasing time: t=0.25 after the previous t=0.3",
     gyro_csv="".join(rows("gyro.csv")[:8] + [rows("gyro.csv")[6]] + rows("gyro.csv")[8:]))
case("duplicate-time", E + "sun.csv:5: duplicate time: t=0.4 equals the previous row's t=0.4",
     sun_csv=with_row("sun.csv", 3, "0.4," + rows("sun.csv")[3].split(",", 1)[1].rstrip("\n")))
case("duplicated-row", E + "joints.csv:12: duplicate time: t=0.45 equals the previous row's t=0.45",
     joints_csv="".join(rows("joints.csv")[:11] + [rows("joints.csv")[10]] +
                        rows("joints.csv")[11:]))
case("wrong-field-count", E + "joints.csv:9: wrong number of fields: expected 12 fields, found 11",
     joints_csv=with_row("joints.csv", 7, rows("joints.csv")[8].rstrip("\n").rsplit(",", 1)[0]))
case("truncated-last-line", E + "joints.csv:42: truncated last line (no newline at end of file)",
     joints_csv=BASE["joints.csv"].rstrip("\n").rsplit(",", 3)[0])
case("sun-valid-not-boolean", E + "sun.csv:5: value 2 in column 'valid' must be 0 or 1",
     sun_csv=with_row("sun.csv", 3, rows("sun.csv")[4].rstrip("\n")[:-1] + "2"))
case("sun-out-of-range", E + "sun.csv:3: value 1.5 in column 's1' out of physical range [-1, 1]",
     sun_csv=with_row("sun.csv", 1, "0.2,1.5," + rows("sun.csv")[2].split(",", 2)[2].rstrip("\n")))


def truth_with_scaled_quaternion(row, factor):
    r = rows("truth.csv")
    fields = r[row + 1].rstrip("\n").split(",")
    for k in range(4, 8):
        fields[k] = repr(float(fields[k]) * factor)
    r[row + 1] = ",".join(fields) + "\n"
    return "".join(r)


case("truth-quaternion-not-unit", E + "truth.csv:4: quaternion (qw,qx,qy,qz) has norm 1.1",
     truth_csv=truth_with_scaled_quaternion(2, 1.1))
def gps_from_truth(bad_row):
    out = ["t,x,y,z,sx,sy,sz\n"]
    for i, l in enumerate(rows("truth.csv")[1:]):
        f = l.split(",")
        out.append(",".join(f[:4] + ["0.01", "0.01", "0" if i == bad_row else "0.02"]) + "\n")
    return "".join(out)


case("gps-sigma-zero", E + "gps.csv:4: value 0 in column 'sz' out of physical range",
     gps_csv=gps_from_truth(2))
case("yaml-unreadable", E + "rover.yaml:4: unreadable YAML",
     rover_yaml=BASE["rover.yaml"].replace("name: rocky7", "name: [rocky7", 1))
case("yaml-unknown-key", E + "rover.yaml:21: key 'gyro.noise_rad': unknown key",
     rover_yaml=yaml_sub(r"^  noise_rad_s:", "  noise_rad:"))
case("yaml-wrong-type", E + "rover.yaml:18: key 'gravity_mps2': expected a number",
     rover_yaml=yaml_sub(r"^gravity_mps2: .*$", "gravity_mps2: strong"))
case("yaml-negative-noise", E + "rover.yaml:21: key 'gyro.noise_rad_s': value -0.001 out of range",
     rover_yaml=yaml_sub(r"^  noise_rad_s: .*$", "  noise_rad_s: -0.001"))
# A list as a key: valid YAML, no rover.yaml key (found by fuzz_rover_yaml: it aborted the run).
case("yaml-key-not-text", E + "rover.yaml:21: key 'gyro': a key must be plain text",
     rover_yaml=yaml_sub(r"^  noise_rad_s:", "  [noise_rad_s]:"))
case("yaml-format-version", E + "rover.yaml:2: key 'format': unsupported format version 2",
     rover_yaml=yaml_sub(r"^format: 1$", "format: 2"))
case("urdf-unreadable-xml", E + "rover.urdf: unreadable URDF",
     rover_urdf=BASE["rover.urdf"].replace("</robot>", "", 1))
case("urdf-wheel-joint-missing", E + "rover.urdf: joint 'wheel_6' (joints.csv column 'psi6') is not "
     "in the URDF", rover_urdf=urdf_sub(r'<link name="wheel_6">.*?</joint>', ""))
case("urdf-joint-not-mapped", E + "rover.urdf: joint 'wheel_one' (joints.csv column 'psi1') is not "
     "in the URDF", rover_yaml=yaml_sub(r"^  psi1: wheel_1$", "  psi1: wheel_one"))
case("urdf-nonpositive-radius", E + "rover.urdf: wheel link of joint 'wheel_1' has no cylinder "
     "geometry giving a positive radius",
     rover_urdf=BASE["rover.urdf"].replace('radius="0.065"', 'radius="-0.065"', 1))
case("binary-file", E + "joints.csv:3: binary content",
     joints_csv="".join(rows("joints.csv")[:2]).encode() + bytes(range(256)) * 4)
case("yaml-binary", E + "rover.yaml:2: binary content (NUL byte at column 7): not a text file",
     rover_yaml=BASE["rover.yaml"].replace("format: 1", "format\0: 1", 1).encode())
case("yaml-empty", E + "rover.yaml: expected a YAML mapping at the top level", rover_yaml="")
case("urdf-binary", E + "rover.urdf:1: binary content (NUL byte at column 1): not a text file",
     rover_urdf=bytes(range(256)) * 4)
case("file-too-large", E + "gyro.csv: file of 31367 bytes (31.4 kB) is larger than the input limit "
     "of 20000 bytes", env="TRAVERSE_MAX_INPUT_BYTES=20000",
     gyro_csv=BASE["gyro.csv"] + ("#" + "x" * 99 + "\n") * 300)
case("file-too-large-sparse", E + "joints.csv: file of 2500000000 bytes",
     grow="joints.csv 2500000000")

# --- accepted: the same numbers as the clean log ---------------------------------------------
case("clean", "exit 0\nlines 0")
case("bom-header", "exit 0\nlines 0\nsame-outputs",
     **{n.replace(".", "_"): "\ufeff" + BASE[n] for n in STREAMS})
case("crlf-line-ends", "exit 0\nlines 0\nsame-outputs",
     **{n.replace(".", "_"): BASE[n].replace("\n", "\r\n") for n in STREAMS})
case("bom-crlf-comments", "exit 0\nlines 0\nsame-outputs",
     **{n.replace(".", "_"): "\ufeff# exported by a test\r\n\r\n" +
        BASE[n].replace("\n", "\r\n").replace("\r\n", "\r\n# a comment\r\n", 3) for n in STREAMS})

# --- usable but dirty: the run succeeds and warns --------------------------------------------
case("gyro-gap", "exit 0\nlines 1\nstderr warning: gyro.csv: gap of 0.6 s at t=0.8",
     gyro_csv="".join(l for i, l in enumerate(rows("gyro.csv"))
                      if i == 0 or not 0.8 < float(l.split(",")[0]) < 1.4))
case("stream-ends-early", "exit 0\nlines 1\nstderr warning: gyro.csv: ends at t=1.0, 1.0 s before joints.csv (t=2.0)",
     gyro_csv="".join(l for i, l in enumerate(rows("gyro.csv"))
                      if i == 0 or float(l.split(",")[0]) <= 1.0))
case("sun-all-invalid", "exit 0\nlines 1\nstderr warning: sun.csv: no valid reading (all 11 rows have valid = 0)",
     sun_csv="".join(l if i == 0 else l.rstrip("\n")[:-1] + "0\n"
                     for i, l in enumerate(rows("sun.csv"))))
case("sun-shifted", "exit 0\nlines 1\nstderr warning: sun.csv: does not overlap joints.csv in time: t 1000.0 .. 1002.0 s",
     sun_csv="".join(l if i == 0 else repr(float(l.split(",")[0]) + 1000) + "," +
                     l.split(",", 1)[1] for i, l in enumerate(rows("sun.csv"))))


case("gyro-spike", "exit 0\nstderr warning: gyro.csv: spike in wz at t=1.0: 2.00",
     gyro_csv=with_row("gyro.csv", 20, "1," + repr(2.0 + float(rows("gyro.csv")[21].split(",")[1]))))
case("sun-out-of-view", "exit 0\nstderr warning: sun.csv: 3 valid readings outside the 160 deg field of "
     "view from t=0.8 to t=1.2",
     sun_csv="".join(l if not 0.7 < float(l.split(",")[0]) < 1.3 else l.split(",")[0] +
                     ",0.7,-0.7,1\n" for l in rows("sun.csv")[1:]).join([rows("sun.csv")[0], ""]))

def main():
    if os.path.isdir(OUT):
        for entry in os.listdir(OUT):
            if os.path.isdir(os.path.join(OUT, entry)):
                shutil.rmtree(os.path.join(OUT, entry))
    for name, expected, changes in CASES:
        d = os.path.join(OUT, name)
        os.makedirs(d)
        files = dict(BASE)
        files.update(changes)
        extra = []
        for key in ("env", "grow"):
            if key in files:
                extra.append(key + " " + files.pop(key))
        for fname, text in files.items():
            if text is None:
                continue
            data = text if isinstance(text, bytes) else text.encode()
            with open(os.path.join(d, fname), "wb") as f:
                f.write(data)
        with open(os.path.join(d, "expected.txt"), "w") as f:
            f.write("\n".join([expected] + extra) + "\n")
    print(f"wrote {len(CASES)} cases to {os.path.normpath(OUT)}")


main()
