#!/usr/bin/python3
"""Hand-worked delta values for tests/unit/test_delta_twin.cpp.

Independent of the twin: Marlin's inverse kinematics written out, and the true effector
position found by Newton's method on the three rod-length equations (not trilateration).
Firmware: rod 250, radius 140; truth: rod 251. Run: /usr/bin/python3 tests/reference/delta_hand.py
"""
import math

TOWERS = [(140 * math.cos(math.radians(a)), 140 * math.sin(math.radians(a))) for a in (210, 330, 90)]


def carriage_heights(rod, x, y, z):
    return [z + math.sqrt(rod * rod - (tx - x) ** 2 - (ty - y) ** 2) for tx, ty in TOWERS]


def det3(m):
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))


def effector(carriages, rod):
    x, y, z = 0.0, 0.0, min(carriages) - 200
    for _ in range(60):
        f = [(x - tx) ** 2 + (y - ty) ** 2 + (z - c) ** 2 - rod * rod for (tx, ty), c in zip(TOWERS, carriages)]
        j = [[2 * (x - tx), 2 * (y - ty), 2 * (z - c)] for (tx, ty), c in zip(TOWERS, carriages)]
        d = det3(j)
        step = []
        for col in range(3):
            m = [row[:] for row in j]
            for r in range(3):
                m[r][col] = -f[r]
            step.append(det3(m) / d)
        x, y, z = x + step[0], y + step[1], z + step[2]
    return x, y, z


if __name__ == "__main__":
    print("IK (10, 20, 5):", ["%.10f" % v for v in carriage_heights(250, 10, 20, 5)])
    # Homing puts each carriage at the true home; the firmware counts from its own home, so a
    # carriage sits sqrt(251^2 - 140^2) - sqrt(250^2 - 140^2) higher than the firmware thinks.
    shift = math.sqrt(251 ** 2 - 140 ** 2) - math.sqrt(250 ** 2 - 140 ** 2)
    for x, y in [(20, 0), (0, 20), (0, -20), (20, 20), (-20, -20), (20, -20)]:
        c = [h + shift for h in carriage_heights(250, x, y, 0.2)]
        print((x, y), "%.9f %.9f %.9f" % effector(c, 251))
