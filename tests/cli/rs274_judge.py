#!/usr/bin/python3
"""LinuxCNC's own interpreter as the judge of `calbox compensate`.

For every job (the shared real ones and the hand-made cases of rs274_cases.py) the original and the
compensated copy are read by `rs274` (linuxcnc-uspace), the work zero given to both through its
parameter file (#5221/#5222, inches). The correction is a planar result written here with a field
this script evaluates itself (a reference model, not calbox's): the machine lands at
c + e(c), so each point of the copy is carried to where the tool really goes and must lie on the
original's motion, reaching every one of its endpoints in order, at the same Z, by the same kind
of move (traverse or feed); arcs are checked along their sweep. Spindle, coolant, dwell, tool,
feed and stop commands come in the same order, after the same original move. A job rs274 refuses
is refused by calbox; a job calbox refuses alone is one of the named deliberate differences.
Then each job again (the real ones as grbl's) placed by the camera at a sheet's corner and turned 3.5 degrees with it
(--work-zero camera, a stock file written here): the original's motion as rs274 reads it, turned
about the work zero, against the copy landed through the field; a job with offsets of its own
(G10, G92, G55..) must be refused.

usage: rs274_judge.py CALBOX DATA_DIR [--only NAME] [--keep DIR] [--mutations N]

--mutations N: the differential fuzzer. N jobs made by mutating the hand-made cases and the
first lines of the real jobs (a character dropped, doubled or changed, a word's letter or a
number's digit swapped, blanks and comments put in), each through calbox and rs274 as above: a
job rs274 refuses is refused by calbox, a job calbox writes is judged right; calbox may refuse
more than rs274 (counted).
"""
import json
import math
import os
import re
import subprocess
import sys
import tempfile

from rs274_cases import (CALBOX_ALONE, CASES, START_AT_ZERO, TOOL_RADIUS_MM, TRACKED, landing,
                         result_json)


class Refused(Exception):
    pass


def run_rs274(path, work, zero_mm):
    # rs274 writes its parameters back when it ends: each run starts from a fresh file. Every
    # tool number a job may ask for is in its table.
    var, tools = os.path.join(work, "judge.var"), os.path.join(work, "judge.tbl")
    if not os.path.exists(tools):
        with open(tools, "w") as f:
            f.write("".join("T%d P%d D3.175 Z+0 ;\n" % (t, t) for t in range(1, 100)))
    # rs274 killed by a signal has judged nothing (once, under a loaded machine, SIGBUS on a job
    # it reads whole when alone): run again, and a judge that keeps dying fails the test rather
    # than counting as a refusal.
    for attempt in range(3):
        var_file(var, zero_mm)
        out = subprocess.run(["rs274", "-t", tools, "-v", var, "-g", path], capture_output=True,
                             text=True, stdin=subprocess.DEVNULL, timeout=300)
        if out.returncode >= 0:
            break
        print("rs274 died of signal %d on %s (attempt %d)" % (-out.returncode, path, attempt + 1))
    else:
        raise RuntimeError("rs274 died of signal %d on %s three times: no judgement"
                           % (-out.returncode, path))
    text = out.stdout + out.stderr
    if out.returncode != 0:
        lines = [l for l in text.splitlines() if l.strip() and not re.match(r"\s*\d+ N", l)
                 and l.strip() != "executing"]
        raise Refused(lines[0] if lines else "rs274 exit %d" % out.returncode)
    return text


def canon(text, start=None):
    """rs274's canonical commands -> (motion, events): motion is a list of primitives in machine
    millimetres; events are (command, arguments, primitives done before it)."""
    unit = 1.0
    g5x = [0.0] * 3
    g92 = [0.0] * 3
    plane = "XY"
    pos = start
    motion, events = [], []
    inverse_time = False
    feed = None
    for line in text.splitlines():
        m = re.match(r"\s*\d+ N\S*\s+([A-Z_0-9]+)\((.*)\)\s*$", line)
        if not m:
            continue
        name, args = m.group(1), m.group(2)
        if name == "USE_LENGTH_UNITS":
            unit = 25.4 if "INCHES" in args else (10.0 if "CM" in args else 1.0)
            continue
        if name == "SET_FEED_MODE":
            inverse_time = args.strip().split(",")[-1].strip() not in ("0", "CANON_UNITS_PER_MINUTE")
            continue
        values = []
        for a in args.split(","):
            try:
                values.append(float(a))
            except ValueError:
                values.append(a.strip())
        if name == "SET_G5X_OFFSET":
            g5x = [values[1] * unit, values[2] * unit, values[3] * unit]
        elif name == "SET_G92_OFFSET":
            g92 = [values[0] * unit, values[1] * unit, values[2] * unit]
        elif name == "SELECT_PLANE":
            plane = "XY" if "XY" in args else ("XZ" if "XZ" in args else "YZ")
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "STRAIGHT_PROBE"):
            end = [values[i] * unit + g5x[i] + g92[i] for i in range(3)]
            if pos is not None and max(abs(end[i] - pos[i]) for i in range(3)) < 1e-9:
                continue  # a move to where the tool stands does nothing
            motion.append({"kind": "traverse" if name == "STRAIGHT_TRAVERSE" else "feed",
                           "from": pos, "to": end})
            pos = end
        elif name == "ARC_FEED":
            e1, e2, c1, c2, turns, axis_end = values[0:6]
            off = [g5x[i] + g92[i] for i in range(3)]
            # The plane's first and second axes and its normal, as canon orders them.
            order = {"XY": (0, 1, 2), "XZ": (2, 0, 1), "YZ": (1, 2, 0)}[plane]
            end = [0.0] * 3
            centre = [0.0, 0.0]
            end[order[0]] = e1 * unit + off[order[0]]
            end[order[1]] = e2 * unit + off[order[1]]
            end[order[2]] = axis_end * unit + off[order[2]]
            centre[0] = c1 * unit + off[order[0]]
            centre[1] = c2 * unit + off[order[1]]
            motion.append({"kind": "feed", "from": pos, "to": end, "arc": True, "order": order,
                           "centre": centre, "turns": int(turns)})
            pos = end
        elif name in TRACKED:
            if name == "SET_FEED_RATE" and (inverse_time or values[0] == feed):
                continue  # per move under G93; the same rate again changes nothing
            if name == "SET_FEED_RATE":
                feed = values[0]
            events.append((name, tuple(round(v, 3) if isinstance(v, float) else v
                                       for v in values), len(motion)))
    return motion, events


def arc_point(p, t):
    """The point at share t of an arc primitive's sweep (XYZ, machine mm)."""
    o = p["order"]
    s, e, c = p["from"], p["to"], p["centre"]
    a0 = math.atan2(s[o[1]] - c[1], s[o[0]] - c[0])
    a1 = math.atan2(e[o[1]] - c[1], e[o[0]] - c[0])
    r0 = math.hypot(s[o[0]] - c[0], s[o[1]] - c[1])
    r1 = math.hypot(e[o[0]] - c[0], e[o[1]] - c[1])
    turns = p["turns"]
    if turns > 0:
        sweep = (a1 - a0) % (2 * math.pi)
        if sweep <= 1e-12:
            sweep += 2 * math.pi
        sweep += 2 * math.pi * (turns - 1)
    else:
        sweep = -((a0 - a1) % (2 * math.pi))
        if sweep >= -1e-12:
            sweep -= 2 * math.pi
        sweep -= 2 * math.pi * (-turns - 1)
    a = a0 + sweep * t
    r = r0 + (r1 - r0) * t
    q = [0.0] * 3
    q[o[0]] = c[0] + r * math.cos(a)
    q[o[1]] = c[1] + r * math.sin(a)
    q[o[2]] = s[o[2]] + (e[o[2]] - s[o[2]]) * t
    return q, sweep


def nearest_share(p, q, after=0.0):
    """(distance, share) from q to primitive p: the share along it of its nearest point; on an
    arc of several turns (P), which passes each place once a turn, the nearest within half a
    turn on from share `after` (the copy's points move on by less)."""
    s, e = p["from"], p["to"]
    if not p.get("arc"):
        d = [e[i] - s[i] for i in range(3)]
        dd = sum(v * v for v in d)
        t = 0.0 if dd == 0 else max(0.0, min(1.0, sum((q[i] - s[i]) * d[i] for i in range(3)) / dd))
        pt = [s[i] + d[i] * t for i in range(3)]
        return math.dist(pt, q), t
    # An arc: coarse samples, then refined about the nearest.
    _, sweep = arc_point(p, 0.0)
    n = max(16, int(abs(sweep) / 0.05))
    first, last = 0, n
    if abs(sweep) > 2 * math.pi:
        first = max(0, int(math.floor(after * n)) - 1)
        last = min(n, first + 2 + int(math.ceil(n * math.pi / abs(sweep))))
    best = min(range(first, last + 1), key=lambda k: math.dist(arc_point(p, k / n)[0], q))
    lo, hi = max(0.0, (best - 1) / n), min(1.0, (best + 1) / n)
    for _ in range(60):
        m1, m2 = lo + (hi - lo) / 3, hi - (hi - lo) / 3
        if math.dist(arc_point(p, m1)[0], q) < math.dist(arc_point(p, m2)[0], q):
            hi = m2
        else:
            lo = m1
    t = (lo + hi) / 2
    return math.dist(arc_point(p, t)[0], q), t


def judge(original, copy, tolerance_mm, allow_raw):
    """Problems found comparing the copy's motion, landed, with the original's."""
    motion, events = original
    copy_motion, copy_events = copy
    problems = []
    # The original's moves before its first known position (from None) only set where it is.
    k = 0
    landed = []
    for c in copy_motion:
        x, y = landing(c["to"][0], c["to"][1])
        landed.append({"kind": c["kind"], "to": [x, y, c["to"][2]]})
    # Each copy point lies on the original move in hand, or ends it (moving on to the next).
    # G28, G30 and G53 go to the controller's own places in machine coordinates, passed as
    # written: there a traverse's raw end is the original's.
    raw_places = allow_raw
    done_at = []  # for each copy point, how many original moves are complete after it
    share = 0.0
    for j, c in enumerate(landed):
        if k >= len(motion):
            problems.append("the copy moves on after the original's last move, to %s" % c["to"])
            break
        p = motion[k]
        at_end = math.dist(p["to"], c["to"]) <= tolerance_mm
        if raw_places and p["kind"] == "traverse" and \
                math.dist(p["to"], copy_motion[j]["to"]) <= 1e-4:
            at_end, d, t = True, 0.0, 1.0
        elif p["from"] is None:
            d, t = math.dist(p["to"], c["to"]), 1.0
        else:
            d, t = nearest_share(p, c["to"], share)
        # A whole circle ends where it starts: it is done when the copy has gone round.
        whole_circle = p.get("arc") and p["from"] is not None and \
            math.dist(p["from"], p["to"]) <= tolerance_mm
        finishes = at_end and (not whole_circle or share > 0.5)
        # An arc of several turns passes its end once a turn: it ends in its last half turn.
        if finishes and p.get("arc") and p["from"] is not None:
            sweep = abs(arc_point(p, 0.0)[1])
            finishes = sweep <= 2 * math.pi or t >= 1 - math.pi / sweep
        if not finishes and (d > tolerance_mm or t < share - 1e-6 or p["from"] is None):
            problems.append("copy point %d %s is %.4f mm off the original's move %d (%s to %s)"
                            % (j, ["%.4f" % v for v in c["to"]], d, k, p["from"], p["to"]))
            break
        if c["kind"] != p["kind"]:
            problems.append("copy point %d is a %s where the original's move %d is a %s"
                            % (j, c["kind"], k, p["kind"]))
            break
        share = t
        if finishes:
            k += 1
            share = 0.0
        done_at.append(k)
    if not problems and k < len(motion):
        problems.append("the copy stops after %d of the original's %d moves (next to %s)"
                        % (k, len(motion), motion[k]["to"]))
    if not problems:
        # Events after the same number of completed original moves, in the same order.
        def placed(evs, done):
            return [(n, a, done[i - 1] if i > 0 else 0) for n, a, i in evs]
        mine = placed(copy_events, done_at)
        if [(n, a) for n, a, _ in events] != [(n, a) for n, a, _ in mine]:
            problems.append("commands differ: original %s, copy %s" % (
                [(n, a) for n, a, _ in events][:12], [(n, a) for n, a, _ in mine][:12]))
        else:
            for (n, a, i), (_, _, j) in zip(events, mine):
                if i != j:
                    problems.append("%s%s comes after %d of the original's moves, in the copy "
                                    "after %d" % (n, a, i, j))
                    break
    return problems


def with_end(path, judged):
    """grbl runs a file to its end; LinuxCNC wants M2, M30 or a closing '%': the job at `path`
    written to `judged` with an M2 after it."""
    with open(path, errors="replace") as f, open(judged, "w") as g:
        g.write(f.read().rstrip("\n%") + "\nM2\n")


def var_file(path, zero_mm):
    with open(path, "w") as f:
        f.write("5220 1.000000\n5221 %.6f\n5222 %.6f\n" % (zero_mm[0] / 25.4, zero_mm[1] / 25.4))


MUTATION_CHARACTERS = "XYZGIJKRFSMPQLNOEe0123456789.-+ \t()%;[#"


def mutated_jobs(seeds, count, rng):
    """`count` mutations of the seed texts: (name, text)."""
    out = []
    for n in range(count):
        name, text = seeds[rng.randrange(len(seeds))]
        chars = list(text)
        for _ in range(rng.randint(1, 3)):
            at = rng.randrange(len(chars)) if chars else 0
            kind = rng.randrange(4)
            if kind == 0 and chars:
                del chars[at]
            elif kind == 1:
                chars.insert(at, rng.choice(MUTATION_CHARACTERS))
            elif kind == 2 and chars:
                chars[at] = rng.choice(MUTATION_CHARACTERS)
            elif chars:
                chars.insert(at, chars[at])
        out.append(("%s~%d" % (name, n), "".join(chars)))
    return out


def fuzz(calbox, data, work, count):
    import random
    rng = random.Random(56)
    seeds = [(name, text) for name, _, text in CASES]
    for folder in ("cnc", "laser"):
        for dirpath, _, files in sorted(os.walk(os.path.join(data, "gcode", folder))):
            for f in sorted(files):
                with open(os.path.join(dirpath, f), errors="replace") as h:
                    head = "".join(h.readlines()[:60])
                seeds.append((f, head + "\nM2\n"))
    results = os.path.join(work, "result_linuxcnc.json")
    with open(results, "w") as f:
        json.dump(result_json("linuxcnc"), f)
    zero = (120.0, 80.0)
    counts = {"right": 0, "refused by both": 0, "refused by calbox alone": 0}
    failures = []
    for name, text in mutated_jobs(seeds, count, rng):
        path = os.path.join(work, "fuzz.ngc")
        out = os.path.join(work, "fuzz.compensated.ngc")
        with open(path, "w") as f:
            f.write(text)
        if os.path.exists(out):
            os.remove(out)
        try:
            run = subprocess.run([calbox, "compensate", "--result", results, path, "--work-zero",
                                  "%g,%g" % zero, "-o", out], capture_output=True, text=True,
                                 stdin=subprocess.DEVNULL, timeout=60)
        except subprocess.TimeoutExpired:
            failures.append("%s: calbox hung (60 s)" % name)
            continue
        if run.returncode < 0 or "terminate called" in run.stderr:
            failures.append("%s: calbox crashed: %s" % (name, run.stderr.strip()[-200:]))
            continue
        try:
            original = canon(run_rs274(path, work, zero))
        except Refused:
            if run.returncode == 0:
                failures.append("%s: rs274 refuses it, calbox compensated it:\n%s" % (name, text))
            else:
                counts["refused by both"] += 1
            continue
        if run.returncode != 0:
            counts["refused by calbox alone"] += 1
            continue
        try:
            copy = canon(run_rs274(out, work, zero))
        except Refused as e:
            failures.append("%s: rs274 refuses the copy (%s):\n%s" % (name, e, text))
            continue
        raw_places = re.search(r"G\s*(28|30|53)(?![0-9.])", text, re.I) is not None
        inches = re.search(r"G\s*2\s*0(?![0-9.])", text, re.I) is not None
        tolerance = 0.002 + (2 * 0.00005 * 25.4 * math.sqrt(3) if inches else 0.0)
        problems = judge(original, copy, tolerance, raw_places)
        if problems:
            failures.append("%s: %s:\n%s" % (name, problems[0], text))
        else:
            counts["right"] += 1
    print("%d mutated jobs: " % count + "; ".join("%d %s" % (v, k) for k, v in counts.items()))
    for f in failures[:10]:
        print("FAIL " + f)
    if len(failures) > 10:
        print("... and %d more" % (len(failures) - 10))
    sys.exit(1 if failures else 0)


def main():
    args = sys.argv[1:]
    calbox, data = args[0], args[1]
    if not os.path.isdir(os.path.join(data, "gcode")):
        # Like the suite's other readers of ../shared: skipped (ctest's 77), not failed.
        print("rs274_judge: no real jobs at %s: skipped" % os.path.join(data, "gcode"))
        sys.exit(77)
    only = args[args.index("--only") + 1] if "--only" in args else None
    keep = args[args.index("--keep") + 1] if "--keep" in args else None
    work = keep or tempfile.mkdtemp()
    os.makedirs(work, exist_ok=True)
    if "--mutations" in args:
        fuzz(calbox, data, work, int(args[args.index("--mutations") + 1]))
    results = {}
    for firmware in ("linuxcnc", "grbl"):
        results[firmware] = os.path.join(work, "result_%s.json" % firmware)
        with open(results[firmware], "w") as f:
            json.dump(result_json(firmware), f)
    jobs = []
    root = os.path.join(data, "gcode")
    for folder in ("cnc", "laser"):
        for dirpath, _, files in sorted(os.walk(os.path.join(root, folder))):
            for name in sorted(files):
                path = os.path.join(dirpath, name)
                for flavour in ("linuxcnc", "grbl"):
                    jobs.append((name, flavour, path))
    for name, flavour, text in CASES:
        path = os.path.join(work, name + ".ngc")
        with open(path, "w") as f:
            f.write(text)
        jobs.append((name, flavour, path))
    zero = (120.0, 80.0)
    failures, counts = [], {"right": 0, "refused by both": 0, "refused by calbox alone": 0}
    for name, flavour, path in jobs:
        if only and only != name:
            continue
        label = "%s (%s)" % (name, flavour)
        out = os.path.join(work, "%s.%s.compensated.ngc" % (name, flavour))
        if os.path.exists(out):
            os.remove(out)
        run = subprocess.run([calbox, "compensate", "--result", results[flavour], path,
                              "--work-zero", "%g,%g" % zero, "-o", out]
                             + (["--start-at", "0,0"] if name in START_AT_ZERO else [])
                             + (["--tool-radius", "%.6f" % TOOL_RADIUS_MM[name]]
                                if name in TOOL_RADIUS_MM else []),
                             capture_output=True, text=True, stdin=subprocess.DEVNULL, timeout=600)
        # grbl runs a file to its end; LinuxCNC wants M2, M30 or a closing '%' (a deliberate
        # difference for grbl's jobs: both sides are read with an M2 after them).
        judged_path, judged_out = path, out
        if flavour == "grbl":
            judged_path = os.path.join(work, "%s.%s.judged.ngc" % (name, flavour))
            judged_out = os.path.join(work, "%s.%s.compensated.judged.ngc" % (name, flavour))
            with_end(path, judged_path)
        try:
            start = [0.0, 0.0, 0.0] if name in START_AT_ZERO else None
            original = canon(run_rs274(judged_path, work, zero), start)
            rs_refusal = None
        except Refused as e:
            rs_refusal = str(e)
        if rs_refusal is not None:
            if run.returncode == 0:
                failures.append("%s: rs274 refuses it (%s), calbox compensated it" % (label, rs_refusal))
            else:
                counts["refused by both"] += 1
                print("%s: refused by both: rs274 '%s'; calbox '%s'" % (label, rs_refusal, run.stderr.strip()))
            continue
        if run.returncode != 0:
            if (name, flavour) in CALBOX_ALONE:
                counts["refused by calbox alone"] += 1
                print("%s: refused by calbox alone, deliberately (%s): %s" % (
                    label, CALBOX_ALONE[(name, flavour)], run.stderr.strip()))
            else:
                failures.append("%s: rs274 runs it, calbox refused: %s" % (label, run.stderr.strip()))
            continue
        if os.path.exists(out) is False:
            failures.append("%s: calbox exit 0 without its output" % label)
            continue
        if flavour == "grbl":
            with_end(out, judged_out)
        try:
            copy = canon(run_rs274(judged_out, work, zero), start)
        except Refused as e:
            failures.append("%s: rs274 refuses the compensated copy: %s" % (label, e))
            continue
        with open(path, errors="replace") as f:
            inches = re.search(r"G\s*2\s*0(?![0-9.])", f.read(), re.I) is not None
        # rs274 prints 4 decimals of the program's unit: an inch job's figures carry its rounding
        # (half of 0.0001 inch) on both sides.
        tolerance = 0.002 + (2 * 0.00005 * 25.4 * math.sqrt(3) if inches else 0.0)
        with open(path, errors="replace") as f:
            raw_places = re.search(r"G\s*(28|30|53)(?![0-9.])", f.read(), re.I) is not None
        problems = judge(original, copy, tolerance, raw_places)
        if problems:
            failures.append("%s: %s" % (label, problems[0]))
        else:
            counts["right"] += 1
            print("%s: right (%d moves, %d in the copy, %d commands in order)" % (
                label, len(original[0]), len(copy[0]), len(original[1])))
    print("; ".join("%d %s" % (v, k) for k, v in counts.items()))
    placed_pass(calbox, jobs, results, work, zero, only, failures)
    for f in failures:
        print("FAIL " + f)
    sys.exit(1 if failures else 0)


# A job placed by the camera at a sheet's corner and turned with it (calbox compensate
# --work-zero camera): the same jobs, their original motion as rs274 reads it turned about the
# work zero by the sheet's turn, against the copy landed through the field.
PLACED_TURN_DEG = 3.5
OWN_OFFSETS = re.compile(r"G\s*(10|92|5[5-9])(?![0-9])", re.I)


def stock_json(zero, turn_deg):
    a = math.radians(turn_deg)
    along, across = (math.cos(a), math.sin(a)), (-math.sin(a), math.cos(a))
    w, d = 300.0, 200.0
    corners = [zero, (zero[0] + w * along[0], zero[1] + w * along[1]),
               (zero[0] + w * along[0] + d * across[0], zero[1] + w * along[1] + d * across[1]),
               (zero[0] + d * across[0], zero[1] + d * across[1])]
    names = ["front-left", "front-right", "back-right", "back-left"]
    return {"schema": "calbox.stock/1", "machine_fingerprint": "fnv1a64:0000000000000000",
            "corners": [{"name": n, "machine_mm": list(c), "sigma_mm": 0.02}
                        for n, c in zip(names, corners)],
            "rotation_deg": turn_deg, "rotation_sigma_deg": 0.001, "width_mm": w, "depth_mm": d,
            "lighter_than_bed": True, "surface_height_mm": 3.0, "edge_points": [100, 70, 100, 70],
            "edge_points_set_aside": 0, "edge_points_under_glare": 0}


def turned_motion(motion, zero, turn_deg):
    """The motion turned about the work zero in XY; None when an arc lies out of the XY plane."""
    a = math.radians(turn_deg)
    c, s = math.cos(a), math.sin(a)

    def turn(p):
        if p is None:
            return None
        dx, dy = p[0] - zero[0], p[1] - zero[1]
        return [zero[0] + c * dx - s * dy, zero[1] + s * dx + c * dy] + list(p[2:])
    out = []
    # Before the job's first X Y, rs274 reports its moves (Z alone) at its own start, machine
    # X0 Y0: no point of the job's, and calbox passes them as they are.
    xy_known = False
    for m in motion:
        if m.get("arc") and m["order"] != (0, 1, 2):
            return None
        at_start = lambda q: q is not None and abs(q[0]) < 1e-3 and abs(q[1]) < 1e-3  # noqa: E731
        if not xy_known and at_start(m["to"]):
            out.append(m)
            continue
        first = not xy_known
        xy_known = True
        t = dict(m, **{"from": None if first and at_start(m["from"]) else turn(m["from"]),
                       "to": turn(m["to"])})
        if m.get("arc"):
            t["centre"] = turn(m["centre"] + [0.0])[:2]
        out.append(t)
    return out


def placed_pass(calbox, jobs, results, work, zero, only, failures):
    stock = os.path.join(work, "stock.json")
    with open(stock, "w") as f:
        json.dump(stock_json(zero, PLACED_TURN_DEG), f)
    counts = {"right": 0, "refused for offsets of their own": 0, "refused by both": 0,
              "with arcs out of the XY plane, not judged": 0}
    hand_made = {name for name, _, _ in CASES}
    for name, flavour, path in jobs:
        if only and only != name:
            continue
        # The real jobs as grbl's (a router's controller without a rotation of its own), the
        # hand-made ones in their own flavour: the suite's time, not every pairing.
        if flavour != "grbl" and name not in hand_made:
            continue
        label = "%s (%s, placed turned %g deg)" % (name, flavour, PLACED_TURN_DEG)
        out = os.path.join(work, "%s.%s.placed.ngc" % (name, flavour))
        if os.path.exists(out):
            os.remove(out)
        run = subprocess.run([calbox, "compensate", "--result", results[flavour], path,
                              "--work-zero", "camera", "--stock", stock, "-o", out]
                             + (["--tool-radius", "%.6f" % TOOL_RADIUS_MM[name]]
                                if name in TOOL_RADIUS_MM else []),
                             capture_output=True, text=True, stdin=subprocess.DEVNULL, timeout=600)
        judged_path, judged_out = path, out
        if flavour == "grbl":
            judged_path = os.path.join(work, "%s.%s.judged.ngc" % (name, flavour))
            judged_out = os.path.join(work, "%s.%s.placed.judged.ngc" % (name, flavour))
            with_end(path, judged_path)
        try:
            original = canon(run_rs274(judged_path, work, zero), None)
        except Refused:
            if run.returncode == 0:
                failures.append("%s: rs274 refuses it, calbox placed it" % label)
            else:
                counts["refused by both"] += 1
            continue
        with open(path, errors="replace") as f:
            text = f.read()
        if run.returncode != 0:
            if OWN_OFFSETS.search(text) and "job placed turned with the stock" in run.stderr:
                counts["refused for offsets of their own"] += 1
            elif (name, flavour) in CALBOX_ALONE or name in START_AT_ZERO:
                counts["refused by both"] += 1
            else:
                failures.append("%s: calbox refused: %s" % (label, run.stderr.strip()))
            continue
        placed = turned_motion(original[0], zero, PLACED_TURN_DEG)
        if placed is None:
            counts["with arcs out of the XY plane, not judged"] += 1
            continue
        if flavour == "grbl":
            with_end(out, judged_out)
        try:
            copy = canon(run_rs274(judged_out, work, zero), None)
        except Refused as e:
            failures.append("%s: rs274 refuses the placed copy: %s" % (label, e))
            continue
        inches = re.search(r"G\s*2\s*0(?![0-9.])", text, re.I) is not None
        tolerance = 0.002 + (2 * 0.00005 * 25.4 * math.sqrt(3) if inches else 0.0)
        raw_places = re.search(r"G\s*(28|30|53)(?![0-9.])", text, re.I) is not None
        problems = judge((placed, original[1]), copy, tolerance, raw_places)
        if problems:
            failures.append("%s: %s" % (label, problems[0]))
        else:
            counts["right"] += 1
    print("placed turned %g deg at a sheet's corner: " % PLACED_TURN_DEG +
          "; ".join("%d %s" % (v, k) for k, v in counts.items()))


if __name__ == "__main__":
    main()
