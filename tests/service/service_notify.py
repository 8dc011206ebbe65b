#!/usr/bin/python3
"""The box under systemd's supervision, with the test in systemd's place: a datagram socket at
NOTIFY_SOCKET (the protocol sd_notify speaks) and WATCHDOG_USEC set as a unit's WatchdogSec= sets
it. A sim cycle: READY=1 first, the status following the cycle, WATCHDOG=1 all along with no gap
as long as the timeout, STOPPING=1 last. A camera request that hangs for 3 s (the sim board's
fault): the watchdog falls silent for as long, then resumes. An idle box stopped by SIGTERM:
STOPPING=1 and status 0. Usage: service_notify.py CALBOX SOURCE_DIR"""
import os
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time

calbox, top = sys.argv[1], sys.argv[2]
work = tempfile.mkdtemp(prefix="calbox-notify-")
WATCHDOG_S = 1.0
problems = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        problems.append(what)


# Linux's SO_TIMESTAMPNS (its control message SCM_TIMESTAMPNS has the same number).
SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)


class Manager:
    """systemd's end of the notification socket: every datagram, with when it came."""

    def __init__(self, name):
        self.path = os.path.join(work, name + ".sock")
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(self.path)
        # When the kernel queued each datagram, not when this thread got round to reading it: a
        # listener slowed by a loaded machine would otherwise stamp a burst after a silence alike.
        self.sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
        self.sock.settimeout(0.2)
        self.messages = []  # (s, field): the kernel's receive time, CLOCK_REALTIME
        self.lock = threading.Lock()
        self.running = True
        self.thread = threading.Thread(target=self.listen, daemon=True)
        self.thread.start()

    def listen(self):
        while self.running:
            try:
                data, ancillary, _, _ = self.sock.recvmsg(4096, 64)
            except socket.timeout:
                continue
            stamps = [struct.unpack("qq", d[:16]) for level, kind, d in ancillary
                      if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPNS]
            now = stamps[0][0] + stamps[0][1] * 1e-9 if stamps else time.time()
            with self.lock:
                for field in data.decode(errors="replace").split("\n"):
                    if field:
                        self.messages.append((now, field))

    def seen(self):
        with self.lock:
            return list(self.messages)

    def close(self):
        self.running = False
        self.thread.join()
        self.sock.close()

    def wait_for(self, field, seconds, box):
        give_up = time.monotonic() + seconds
        while time.monotonic() < give_up:
            if any(f == field for _, f in self.seen()):
                return True
            if box.poll() is not None:
                return False
            time.sleep(0.05)
        return False


def start_box(manager, name, scenario, extra, journal=False):
    env = dict(os.environ)
    env["NOTIFY_SOCKET"] = manager.path
    env["WATCHDOG_USEC"] = str(int(WATCHDOG_S * 1e6))
    env.pop("WATCHDOG_PID", None)
    env.pop("JOURNAL_STREAM", None)
    err = open(os.path.join(work, name + ".err"), "w")
    if journal:
        # What systemd sets when standard error is the journal's stream: its device and inode.
        st = os.fstat(err.fileno())
        env["JOURNAL_STREAM"] = "%d:%d" % (st.st_dev, st.st_ino)
    return subprocess.Popen([calbox, "run", "--board", "sim", "--scenario", scenario, "--data",
                             os.path.join(work, name), "--console", ""] + extra,
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err,
                            env=env)


def finished(box, seconds, sigterm=False):
    """The box's exit status (SIGTERM first, as systemctl stop sends it); None past `seconds`."""
    if sigterm:
        box.send_signal(signal.SIGTERM)
    try:
        return box.wait(timeout=seconds)
    except subprocess.TimeoutExpired:
        box.kill()
        return None


def watchdog_gaps(messages):
    # systemd counts a silence from READY=1 as from a pet: a loop held up before its first pet
    # (a fast cycle reaching the hung capture within the first quarter second) is silent too.
    times = [t for t, f in messages if f in ("READY=1", "WATCHDOG=1")]
    return times, [b - a for a, b in zip(times, times[1:])]


def log_of(name):
    return open(os.path.join(work, name + ".err"), errors="replace").read()


scenario = os.path.join(top, "tests/scenarios/delta_cycle_small.toml")

# 1. A whole cycle under the watchdog.
manager = Manager("cycle")
box = start_box(manager, "cycle", scenario, ["--auto"])
rc = finished(box, 300)
manager.close()
seen = manager.seen()
fields = [f for _, f in seen]
check(rc == 0, "a sim cycle under the watchdog: exit status %s" % rc)
check(fields[:1] == ["READY=1"], "READY=1 comes first (first: %s)" % (fields[:1] or "nothing"))
statuses = [f[len("STATUS="):] for f in fields if f.startswith("STATUS=")]
check(len(statuses) >= 5, "the status follows the cycle: %d status lines" % len(statuses))
check(statuses[:1] == ["idle, 0 cycles completed: waiting: press to calibrate"],
      "the first status is the idle box's: %s" % statuses[:1])
for step in ("setup-camera", "make-target", "light+capture", "measure", "solve", "apply",
             "verify"):
    check(any(s.startswith("cycle 1: " + step) for s in statuses),
          "a status says the cycle's %s" % step)
check(statuses[-1:] == ["idle, 1 cycle completed: waiting: press to calibrate"],
      "the last status is the idle box with its cycle done: %s" % statuses[-1:])
check(fields[-1:] == ["STOPPING=1"], "STOPPING=1 comes last (last: %s)" % fields[-1:])
times, gaps = watchdog_gaps(seen)
pets = sum(1 for _, f in seen if f == "WATCHDOG=1")
run_s = (seen[-1][0] - seen[0][0]) if seen else 0
check(pets >= run_s / (WATCHDOG_S / 4) * 0.6,
      "WATCHDOG=1 %d times over %.1f s (petted every %.2f s)" % (pets, run_s, WATCHDOG_S / 4))
longest = max(gaps) if gaps else float("inf")
check(longest < WATCHDOG_S,
      "the longest silence of a healthy loop, %.2f s, is under the %.1f s timeout"
      % (longest, WATCHDOG_S))
check("service: the watchdog petted every 0.25 s (timeout 1.0 s)" in log_of("cycle"),
      "the log says how often the watchdog is petted")

# 2. A camera request that does not return for 3 s holds up the loop: no WATCHDOG=1 for that long.
hung = os.path.join(work, "hung.toml")
with open(hung, "w") as f:
    f.write(open(scenario).read() +
            "\n[faults]\ncamera_hangs_at_capture = 3\ncamera_hang_s = 3.0\n")
manager = Manager("hung")
box = start_box(manager, "hung", hung, ["--auto"], journal=True)
came_back = False
give_up = time.monotonic() + 60
while time.monotonic() < give_up and box.poll() is None:
    times, gaps = watchdog_gaps(manager.seen())
    if gaps and max(gaps) > 2.5 and times[-1] - times[0] > 0 and \
            gaps.index(max(gaps)) < len(gaps) - 2:
        came_back = True
        break
    time.sleep(0.1)
times, gaps = watchdog_gaps(manager.seen())
check(came_back and max(gaps) >= 2.9,
      "a hung camera request silences the watchdog for %.2f s (3 s hang), then it resumes"
      % (max(gaps) if gaps else 0))
if not came_back:
    # What the box did, for whoever looks next.
    print("  %d WATCHDOG=1 over %.1f s; the hung box's log:" % (len(times), times[-1] - times[0] if times else 0))
    print("".join("  " + line for line in open(os.path.join(work, "hung.err"), errors="replace").readlines()[-25:]))
rc = finished(box, 30, sigterm=True)
manager.close()
check(rc == 3, "--auto stopped by SIGTERM before its verdict: exit status %s (3)" % rc)
check([f for _, f in manager.seen()][-1:] == ["STOPPING=1"], "STOPPING=1 on the way out")
# Its standard error was "the journal": every line carries its level.
lines = log_of("hung").splitlines()
check(lines and all(line[:1] == "<" and line[2:3] == ">" for line in lines),
      "to the journal every line starts with its level (first: %s)" % lines[:1])
check("<6>calbox: service: the watchdog petted every 0.25 s (timeout 1.0 s)" in lines,
      "an ordinary line is filed as info (<6>)")
check(any(line.startswith("<4>calbox: --auto: stopped before the verdict") for line in lines),
      "a cycle stopped before its verdict is filed as a warning (<4>)")
check(not any(line.startswith("<") for line in log_of("cycle").splitlines()),
      "to a file or a terminal the lines carry no level")

# 2b. A camera that fails: the cycle's error is filed as an error (journalctl -p err finds it).
failing = os.path.join(work, "failing.toml")
with open(failing, "w") as f:
    f.write(open(scenario).read() + "\n[faults]\ncamera_fails_at_capture = 1\n")
manager = Manager("failing")
box = start_box(manager, "failing", failing, ["--auto"], journal=True)
rc = finished(box, 120)
manager.close()
errors = [line for line in log_of("failing").splitlines() if line.startswith("<3>")]
check(log_of("failing").splitlines()[-1:] ==
      ["<3>calbox: the cycle did not complete: camera: frame 1 of 1 never arrived (sensor timeout)"],
      "the run's own last word is filed as an error too: %s" % log_of("failing").splitlines()[-1:])
check(rc == 1 and any("cycle 1: error: camera: " in line for line in errors),
      "a failed capture's cycle error is filed as an error (<3>): %s (exit %s)"
      % (errors[:1], rc))
statuses = [f for _, f in manager.seen() if f.startswith("STATUS=cycle 1: error: camera: ")]
check(len(statuses) == 1, "the status says the cycle's error: %s" % statuses[:1])

# 3. An idle box stopped as systemctl stops it.
manager = Manager("idle")
box = start_box(manager, "idle", scenario, [])
ready = manager.wait_for("READY=1", 30, box)
check(ready, "an idle box says READY=1")
rc = finished(box, 30, sigterm=True)
manager.close()
fields = [f for _, f in manager.seen()]
check(rc == 0, "SIGTERM: exit status %s (0)" % rc)
check(fields[-1:] == ["STOPPING=1"], "STOPPING=1 after SIGTERM (last: %s)" % fields[-1:])

# 4. Without a manager (a box run from a shell) nothing is sent and nothing fails: covered by
# every other test of `calbox run`, which has no NOTIFY_SOCKET.
if problems:
    for name in ("cycle", "hung", "failing", "idle"):
        path = os.path.join(work, name + ".err")
        if os.path.exists(path):
            print("== %s.err (last 15 lines)" % name)
            print("".join(open(path, errors="replace").readlines()[-15:]))
    sys.exit(1)
print("service notifications: all checks pass")
