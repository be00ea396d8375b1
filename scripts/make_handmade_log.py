#!/usr/bin/python3
"""Writes datasets/logs/handmade: a small hand-made traverse log (format 1).

Rocky-7 on flat level ground: 5 s at rest, 10 s driving straight ahead along site +x at
5 cm/s (quintic speed ramps of 1 s), 5 s at rest. Heading gyro at 20 Hz with a constant bias
of 0.002 rad/s, joints at 10 Hz, sun sensor at 2 Hz, accelerometer at 20 Hz; no noise, so the
values can be checked by hand. It stands in for simulator output until `traverse simulate`
exists (issue 3). Regenerate with:  /usr/bin/python3 scripts/make_handmade_log.py
"""
import math
import os
import shutil

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
OUT = os.path.join(ROOT, "datasets", "logs", "handmade")
R = 0.065
V = 0.05
G = 9.80665
BIAS = 0.002
SUN = [-1 / math.sqrt(3), 1 / math.sqrt(3), 1 / math.sqrt(3)]


def speed(t):
    """Quintic ramp up over [5, 6], cruise, ramp down over [14, 15]."""
    def s(u):
        return 10 * u**3 - 15 * u**4 + 6 * u**5
    if t < 5 or t > 15:
        return 0.0
    if t < 6:
        return V * s(t - 5)
    if t > 14:
        return V * s(15 - t)
    return V


def distance(t, dt=1e-3):
    n = int(round(t / dt))
    return sum(speed((k + 0.5) * dt) for k in range(n)) * dt


def fmt(x):
    return repr(float(x))


def write(name, header, rows):
    with open(os.path.join(OUT, name), "w") as f:
        f.write(header + "\n")
        for r in rows:
            f.write(",".join(fmt(x) for x in r) + "\n")


def main():
    os.makedirs(OUT, exist_ok=True)
    rocky = os.path.join(ROOT, "datasets", "rovers", "rocky7")
    shutil.copy(os.path.join(rocky, "rover.urdf"), OUT)
    shutil.copy(os.path.join(rocky, "rover.yaml"), OUT)
    times = lambda hz: [k / hz for k in range(int(20 * hz) + 1)]
    write("gyro.csv", "t,wz", [(t, BIAS) for t in times(20)])
    write("joints.csv", "t,gamma0,gamma1,gamma2,lambda1,lambda2,psi1,psi2,psi3,psi4,psi5,psi6",
          [[t, 0, 0, 0, 0, 0] + [distance(t) / R] * 6 for t in times(10)])
    # Level rover, heading 0: the sun in the sensor frame is SUN itself (K-15).
    rho = math.hypot(SUN[0], SUN[1])
    k = (2 / math.pi) * math.atan2(rho, SUN[2]) / rho
    write("sun.csv", "t,s1,s2,valid", [(t, k * SUN[0], k * SUN[1], 1) for t in times(2)])
    write("accel.csv", "t,ax,ay,az", [(t, 0, 0, G) for t in times(20)])
    write("truth.csv", "t,x,y,z,qw,qx,qy,qz", [(t, distance(t), 0, R + 0.12, 1, 0, 0, 0) for t in times(10)])


if __name__ == "__main__":
    main()
