#!/usr/bin/env python3
"""Frames, signs, units and reproducibility of scripts/import_wvu_pathfinder.py (docs/real-logs.md).

Run by ctest (ImportWvuPathfinder) with the repository root as the only argument. Each check is
against physics or an independent stream of the source file, not against the importer's own
constants: gravity at rest, the accelerometer's forward pulse at every start, the GPS track's
turning, and the raw .mat values.
"""
import filecmp
import os
import subprocess
import sys
import tempfile
import unittest

import h5py
import numpy as np

ROOT = os.path.abspath(sys.argv.pop(1) if len(sys.argv) > 1 else
                       os.path.join(os.path.dirname(__file__), ".."))
IMPORTER = os.path.join(ROOT, "scripts", "import_wvu_pathfinder.py")
REAL = os.path.join(ROOT, "datasets", "real", "wvu-pathfinder")
RUNS = ["s5t1", "test17run"]
WHEEL_RADIUS_M = 0.11
FILES = ["gyro.csv", "accel.csv", "joints.csv", "gps.csv", "rover.urdf", "rover.yaml", "LICENSE",
         "README.md"]


def read_csv(path):
    with open(path) as f:
        header = f.readline().strip().split(",")
    return header, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def import_run(run, outdir):
    subprocess.run([sys.executable, IMPORTER, os.path.join(REAL, run + ".mat"), outdir],
                   check=True)


class ImportedLogs(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.logs = {}
        for run in RUNS:
            d = os.path.join(cls.tmp.name, "a", run)
            import_run(run, d)
            log = {name[:-4]: read_csv(os.path.join(d, name)) for name in FILES if
                   name.endswith(".csv")}
            log["dir"] = d
            cls.logs[run] = log

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def wheel_rates(self, run):
        """Mid-interval times and finite-difference rates (rad/s) of the four wheels."""
        _, j = self.logs[run]["joints"]
        rates = np.diff(j[:, 1:], axis=0) / np.diff(j[:, 0])[:, None]
        return 0.5 * (j[1:, 0] + j[:-1, 0]), rates

    def test_byte_identical_across_runs_and_to_the_bundled_logs(self):
        for run in RUNS:
            again = os.path.join(self.tmp.name, "b", run)
            import_run(run, again)
            bundled = os.path.join(ROOT, "datasets", "logs", "wvu-pathfinder-" + run)
            for name in FILES:
                first = os.path.join(self.logs[run]["dir"], name)
                self.assertTrue(filecmp.cmp(first, os.path.join(again, name), shallow=False),
                                f"{run}/{name} differs between two imports")
                self.assertTrue(filecmp.cmp(first, os.path.join(bundled, name), shallow=False),
                                f"{bundled}/{name} is not what the importer writes today")

    def test_time_zero_is_the_earliest_stamp(self):
        for run in RUNS:
            firsts = [self.logs[run][s][1][0, 0] for s in ("gyro", "accel", "joints", "gps")]
            self.assertEqual(min(firsts), 0.0, run)
            self.assertTrue(all(f >= 0.0 for f in firsts), run)

    def test_headers(self):
        log = self.logs["s5t1"]
        self.assertEqual(log["gyro"][0], ["t", "wx", "wy", "wz"])
        self.assertEqual(log["accel"][0], ["t", "ax", "ay", "az"])
        self.assertEqual(log["joints"][0], ["t", "front_left_wheel", "rear_left_wheel",
                                            "front_right_wheel", "rear_right_wheel"])
        self.assertEqual(log["gps"][0], ["t", "x", "y", "z", "sx", "sy", "sz"])

    def test_gravity_points_up_in_the_body_frame_at_rest(self):
        for run in RUNS:
            t_rate, rates = self.wheel_rates(run)
            t_move = t_rate[np.argmax(np.abs(rates).max(axis=1) > 0.01)]
            _, a = self.logs[run]["accel"]
            rest = a[a[:, 0] < t_move - 0.5, 1:]
            self.assertGreater(len(rest), 500, run)
            f = rest.mean(axis=0)
            # Specific force at rest is the reaction to gravity: +z (up) in the body frame.
            self.assertGreater(f[2], 9.7, run)
            self.assertGreater(f[2] / np.linalg.norm(f), np.cos(np.radians(5)), run)

    def test_each_start_from_rest_is_forward_and_turns_every_wheel_forward(self):
        starts_checked = 0
        for run in RUNS:
            t_rate, rates = self.wheel_rates(run)
            speed = WHEEL_RADIUS_M * np.abs(rates).max(axis=1)
            _, a = self.logs[run]["accel"]
            for k in range(10, len(speed) - 15):
                if not (speed[k] > 0.02 and np.all(speed[k - 10:k] <= 0.02)):
                    continue
                ts = t_rate[k]
                rest = (a[:, 0] > ts - 1.2) & (a[:, 0] < ts - 0.2)
                ramp = (a[:, 0] > ts - 0.2) & (a[:, 0] < ts + 1.5)
                # Velocity gained along body x by the accelerometer (IMU x forward, independent
                # of the wheels): a start is forward when it is positive.
                dv = np.trapz(a[ramp, 1] - a[rest, 1].mean(), a[ramp, 0])
                after = (t_rate > ts) & (t_rate < ts + 1.5)
                self.assertGreater(dv, 0.1, f"{run}: start at {ts:.1f} s is not forward")
                self.assertTrue(np.all(rates[after][-5:] > 0),
                                f"{run}: a wheel turns backwards in the forward start at {ts:.1f} s")
                v_wheels = WHEEL_RADIUS_M * rates[after][-1].mean()
                self.assertLess(abs(dv - v_wheels), 0.3 * v_wheels, f"{run}: {ts:.1f} s")
                starts_checked += 1
        self.assertGreaterEqual(starts_checked, 10)  # 9 in s5t1, 1 in test17run

    def test_yaw_rate_sign_agrees_with_the_gps_track(self):
        _, g = self.logs["s5t1"]["gyro"]
        _, p = self.logs["s5t1"]["gps"]
        # Course over ground from per-second medians of the fixes (the median rejects s5t1's
        # jumps); the rover never reverses (test above), so course change = heading change.
        tb = np.arange(p[0, 0], p[-1, 0] - 1.0, 1.0)
        med = np.array([np.median(p[(p[:, 0] >= t) & (p[:, 0] < t + 1), 1:3], axis=0)
                        for t in tb])
        step = np.diff(med, axis=0)
        course = np.arctan2(step[:, 1], step[:, 0])
        t_course = tb[:-1] + 1.0
        yaw = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:, 3] + g[:-1, 3]) * np.diff(g[:, 0]))])
        agree = disagree = 0
        window = 3
        for i in range(len(course) - window):
            if not np.all(np.linalg.norm(step[i:i + window + 1], axis=1) > 0.3):
                continue
            d_course = np.angle(np.exp(1j * (course[i + window] - course[i])))
            d_yaw = np.interp(t_course[i + window], g[:, 0], yaw) - np.interp(t_course[i], g[:, 0],
                                                                              yaw)
            if abs(d_yaw) < np.radians(20):
                continue
            if np.sign(d_course) == np.sign(d_yaw):
                agree += 1
            else:
                disagree += 1
        self.assertGreaterEqual(agree, 10)
        self.assertEqual(disagree, 0)
        # Net heading change: counter-clockwise seen from above in the ENU site frame.
        self.assertAlmostEqual(np.degrees(yaw[-1]), 296, delta=5)

    def test_values_are_the_source_rotated_and_rounded(self):
        with h5py.File(os.path.join(REAL, "s5t1.mat"), "r") as f:
            raw = {k: np.array(f[k]).reshape(-1) for k in
                   ["Gx", "Gy", "Gz", "Ax", "Ay", "Az", "frontLeftPos", "frontRightPos"]}
            enu = np.array(f["ENUGPS"])
            lon_sigma = np.array(f["LonSigma"]).reshape(-1)
        _, g = self.logs["s5t1"]["gyro"]
        _, a = self.logs["s5t1"]["accel"]
        _, j = self.logs["s5t1"]["joints"]
        _, p = self.logs["s5t1"]["gps"]
        np.testing.assert_allclose(g[:, 1:], np.stack([raw["Gx"], -raw["Gy"], -raw["Gz"]], 1),
                                   atol=5e-8)
        np.testing.assert_allclose(a[:, 1:], np.stack([raw["Ax"], -raw["Ay"], -raw["Az"]], 1),
                                   atol=5e-7)
        np.testing.assert_allclose(j[:, 1], -raw["frontLeftPos"], atol=5e-8)
        np.testing.assert_allclose(j[:, 3], raw["frontRightPos"], atol=5e-8)
        np.testing.assert_allclose(p[:, 1:4], enu, atol=1e-4)  # the authors' own ENU
        np.testing.assert_allclose(p[:, 4], lon_sigma, atol=5e-5)  # sx: east = longitude

    def test_gps_clock_keeps_pace_with_the_gyro(self):
        """test17run's fixes are re-timed by the importer's clock fit (to the wheels); checked
        against the gyro, which the fit does not use: the GPS course's turn rate lags the yaw
        rate by the same time in both halves of the drive (on the file's stamps: 0.45 s, then
        0.85 s)."""
        _, p = self.logs["test17run"]["gps"]
        _, g = self.logs["test17run"]["gyro"]
        span = 2.0
        t = np.arange(p[0, 0] + span, p[-1, 0] - span, 0.05)
        east = [np.interp(t + s * span / 2, p[:, 0], p[:, 1]) for s in (-1, 1)]
        north = [np.interp(t + s * span / 2, p[:, 0], p[:, 2]) for s in (-1, 1)]
        de, dn = east[1] - east[0], north[1] - north[0]
        moving = np.hypot(de, dn) / span > 0.3
        course_rate = np.gradient(np.unwrap(np.arctan2(dn, de)), t)
        n = int(round(span / np.median(np.diff(g[:, 0]))))
        yaw_rate = np.convolve(g[:, 3], np.ones(n) / n, mode="same")
        idx = np.nonzero(moving)[0]
        a, b = t[idx[0]], t[idx[-1]]
        self.assertGreater(b - a, 40.0)
        lags = []
        for lo, hi in ((a, 0.5 * (a + b)), (0.5 * (a + b), b)):
            m = moving & (t >= lo) & (t < hi)
            candidates = np.arange(-3.0, 3.0 + 1e-9, 0.05)
            err = [np.mean((course_rate[m] - np.interp(t[m] + c, g[:, 0], yaw_rate)) ** 2)
                   for c in candidates]
            lags.append(candidates[int(np.argmin(err))])
        self.assertLess(abs(lags[1] - lags[0]), 0.2, lags)
        self.assertLess(max(abs(x) for x in lags), 0.5, lags)

    def test_gps_stops_when_the_accelerometer_does(self):
        """The last GPS motion of test17run ends within 0.3 s of the end of the accelerometer's
        driving vibration (on the file's stamps the fixes stop 1.1 s early)."""
        _, p = self.logs["test17run"]["gps"]
        _, a = self.logs["test17run"]["accel"]
        speed = np.linalg.norm(p[6:, 1:3] - p[:-6, 1:3], axis=1) / (p[6:, 0] - p[:-6, 0])
        t_speed = 0.5 * (p[6:, 0] + p[:-6, 0])
        gps_stop = t_speed[np.nonzero(speed > 0.3)[0][-1]]
        n = 50  # 0.2 s at 250 Hz
        k = len(a) // n
        blocks = a[:k * n, 1].reshape(k, n)
        t_block = a[:k * n, 0].reshape(k, n).mean(axis=1)
        vibration = blocks.std(axis=1)
        accel_stop = t_block[np.nonzero(vibration > 0.2)[0][-1]]
        self.assertLess(abs(gps_stop - accel_stop), 0.3, (gps_stop, accel_stop))

    def test_rtk_sigma_covers_the_spread_at_rest(self):
        _, p = self.logs["test17run"]["gps"]
        t_rate, rates = self.wheel_rates("test17run")
        t_move = t_rate[np.argmax(np.abs(rates).max(axis=1) > 0.01)]
        rest = p[p[:, 0] < t_move]
        self.assertGreater(len(rest), 20)
        spread = rest[:, 1:4].std(axis=0)
        self.assertTrue(np.all(spread < rest[0, 4:7]), f"spread {spread} vs sigma {rest[0, 4:7]}")


class BadInput(unittest.TestCase):
    def run_importer(self, mat, outdir):
        return subprocess.run([sys.executable, IMPORTER, mat, outdir], capture_output=True,
                              text=True)

    def test_missing_file_is_one_line_and_exit_2(self):
        with tempfile.TemporaryDirectory() as tmp:
            r = self.run_importer(os.path.join(tmp, "none.mat"), os.path.join(tmp, "out"))
            self.assertEqual(r.returncode, 2)
            self.assertEqual(r.stderr, os.path.join(tmp, "none.mat") + ":0: file not found\n")
            self.assertFalse(os.path.exists(os.path.join(tmp, "out")))

    def test_not_hdf5_is_one_line_and_exit_2(self):
        with tempfile.TemporaryDirectory() as tmp:
            mat = os.path.join(tmp, "x.mat")
            with open(mat, "w") as f:
                f.write("MATLAB 5.0 MAT-file, not v7.3\n")
            with open(os.path.join(tmp, "LICENSE"), "w") as f:
                f.write("test\n")
            r = self.run_importer(mat, os.path.join(tmp, "out"))
            self.assertEqual(r.returncode, 2)
            self.assertTrue(r.stderr.startswith(mat + ":0: cannot read as MATLAB v7.3"), r.stderr)
            self.assertEqual(r.stderr.count("\n"), 1, r.stderr)

    def test_missing_variable_is_named(self):
        with tempfile.TemporaryDirectory() as tmp:
            mat = os.path.join(tmp, "x.mat")
            with h5py.File(mat, "w") as f:
                f["tTimu"] = np.zeros((1, 3))
            with open(os.path.join(tmp, "LICENSE"), "w") as f:
                f.write("test\n")
            r = self.run_importer(mat, os.path.join(tmp, "out"))
            self.assertEqual(r.returncode, 2)
            self.assertEqual(r.stderr, mat + ":0: variable 'Gx' missing\n")


if __name__ == "__main__":
    unittest.main()
