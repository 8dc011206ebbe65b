#!/usr/bin/python3
"""The console over a real pseudo-terminal, as a person at a serial terminal uses it.

calbox run --console pty on the sim board (a router, the twin's person doing what each prompt
asks but pressing nothing): every command, bad values and unknown keys (the saved file
untouched), an over-long line, a disconnect and a reconnect, the camera's set-up from the
console and a whole cycle started and confirmed from it.
"""
import json
import hashlib
import os
import re
import select
import subprocess
import sys
import tempfile
import termios
import time
import tty

calbox, top = sys.argv[1], sys.argv[2]
work = tempfile.mkdtemp(prefix="calbox-console-")
data = os.path.join(work, "box")
DEADLINE_S = 600  # a whole cycle under the sanitizers


def fail(why):
    print("FAIL:", why)
    try:
        print(open(os.path.join(work, "run.err")).read()[-3000:])
    except OSError:
        pass
    box.kill()
    sys.exit(1)


err = open(os.path.join(work, "run.err"), "w")
box = subprocess.Popen(
    [calbox, "run", "--board", "sim", "--console", "pty", "--operator-hands",
     "--scenario", os.path.join(top, "tests/scenarios/planar_small.toml"), "--data", data],
    stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err)

link = os.path.join(data, "console")
for _ in range(300):
    if os.path.islink(link):
        break
    time.sleep(0.1)
else:
    fail("no console link")


class Terminal:
    def __init__(self):
        self.fd = os.open(link, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)
        termios.tcflush(self.fd, termios.TCIFLUSH)  # what the box said to nobody
        self.buffer = b""
        self.notices = []

    def close(self):
        os.close(self.fd)

    def line(self, timeout_s):
        end = time.time() + timeout_s
        while b"\n" not in self.buffer:
            left = end - time.time()
            if left <= 0 or box.poll() is not None:
                return None
            r, _, _ = select.select([self.fd], [], [], left)
            if r:
                self.buffer += os.read(self.fd, 4096)
        text, self.buffer = self.buffer.split(b"\n", 1)
        return text.decode()

    def send(self, text):
        os.write(self.fd, text.encode())

    def ask(self, command, ok=True):
        """The JSON reply to a command; the notices met on the way are kept."""
        self.send(command + " --json\r")  # a terminal program's Enter
        while True:
            line = self.line(60)
            if line is None:
                fail("no reply to " + command)
            if line.startswith("notice: "):
                self.notices.append(line[8:])
                continue
            reply = json.loads(line)
            if reply["ok"] != ok:
                fail(f"{command}: {reply}")
            return reply

    def text(self, command):
        """A command's text reply: the lines until the console is quiet."""
        self.send(command + "\n")
        lines = []
        while True:
            line = self.line(1.0 if lines else 60)
            if line is None:
                return lines
            if not line.startswith("notice: "):
                lines.append(line)

    def wait_notice(self, start):
        end = time.time() + DEADLINE_S
        while time.time() < end:
            for i, n in enumerate(self.notices):
                if n.startswith(start):
                    del self.notices[: i + 1]
                    return n
            line = self.line(end - time.time())
            if line is None:
                break
            if line.startswith("notice: "):
                self.notices.append(line[8:])
        fail("no notice " + start + "; seen " + repr(self.notices))

    def wait_state(self, state, completed=None, waiting=None):
        end = time.time() + DEADLINE_S
        while time.time() < end:
            s = self.ask("status")
            if s["state"] == state and (completed is None or s["completed"] == completed) and (
                    waiting is None or s["waiting"] == waiting):
                return s
            time.sleep(0.3)
        fail(f"never {state} {waiting or ''}")


t = Terminal()
# version, help, status
# The version is the build's: the project's, then git's commit count and hash in a checkout.
version = subprocess.run([calbox, "--version"], capture_output=True, text=True).stdout.split()[-1]
if not re.fullmatch(r"0\.1\.0(\+git\.\d+\.[0-9a-f]{7,}(\.dirty)?)?", version) or (
        os.path.isdir(os.path.join(top, ".git")) and "+git." not in version):
    fail("calbox --version: " + version)
if t.ask("version")["version"] != version:
    fail("version")
help_lines = "\n".join(t.text("help"))
for command in ["status", "config list", "config get KEY", "config set KEY VALUE", "config save",
                "config reset [KEY]", "start", "confirm", "cancel", "revert", "last", "log [N]",
                "version", "camera calibrate", "camera plane", "capture", "press", "hold"]:
    if command not in help_lines:
        fail("help lacks " + command)
readme = open(os.path.join(top, "docs", "appliance.md")).read()
for entry in t.ask("help")["commands"]:
    if "`" + entry["command"] + "`" not in readme:
        fail("docs/appliance.md does not document " + entry["command"])
s = t.ask("status")
if s["state"] != "idle" or s["waiting"] != "press to calibrate":
    fail(f"status {s}")

# configuration: a good set saved, then bad values and unknown keys leave it as it was
keys = t.ask("config list")["config"]
if keys["cycle.frames_per_capture"]["value"] != "1" or keys["records.keep_cycles"]["unit"] != "cycles":
    fail("config list")
t.ask("config set setup.calibration_views 8")
t.ask("config save")
saved = os.path.join(data, "calbox.toml")
before = open(saved).read()
if "calibration_views = 8" not in before:
    fail("the saved file lacks the set value")
stat_before = os.stat(saved)
r = t.ask("config set cycle.frames_per_capture 40", ok=False)
if "'40' is not a whole number 1 to 16 photos" not in r["error"]:
    fail(r["error"])
r = t.ask("config set cycle.frames 2", ok=False)
if "'cycle.frames' is not a configuration key" not in r["error"]:
    fail(r["error"])
r = t.ask("config set modbus.server tcp:nohost", ok=False)
if "not tcp:HOST:PORT" not in r["error"]:
    fail(r["error"])
if t.ask("config get cycle.frames_per_capture")["value"] != "1":
    fail("a refused value took")
after = os.stat(saved)
if open(saved).read() != before or after.st_mtime_ns != stat_before.st_mtime_ns or after.st_ino != stat_before.st_ino:
    fail("the saved file changed")
t.ask("config set records.keep_cycles 9")
t.ask("config reset records.keep_cycles")
if t.ask("config get records.keep_cycles")["value"] != "50":
    fail("reset")
print("config: set, save, refusals (file untouched), reset")

# The web page's password: kept as a PBKDF2 hash that Python's own hashlib confirms, never itself.
t.ask("web password correct horse")
t.ask("config save")
stored = re.search(r'password = "(pbkdf2-sha256:(\d+):([0-9a-f]+):([0-9a-f]+))"', open(saved).read())
if not stored or "correct horse" in open(saved).read():
    fail("the saved web password is not a hash")
if hashlib.pbkdf2_hmac("sha256", b"correct horse", bytes.fromhex(stored.group(3)),
                       int(stored.group(2))).hex() != stored.group(4):
    fail("the web password's hash does not verify")
r = t.ask("config set web.password plain", ok=False)
if "not a password hash" not in r["error"]:
    fail(r["error"])
t.ask("web password --clear")
if t.ask("config get web.password")["value"] != "":
    fail("web password --clear")
r = t.ask("acknowledge", ok=False)
if "no error to acknowledge" not in r["error"]:
    fail(r["error"])
print("web password: hashed, verified by hashlib, cleared")

# an over-long line is refused whole, and the console goes on
t.send("config set console.device " + "x" * 300 + "\n")
line = t.line(30)
if line != "error: line longer than 256 bytes refused (nothing was done)":
    fail("over-long line: " + repr(line))
v = t.ask("config get console.device")["value"]
if v != "stdin":
    fail("the over-long line did something: " + repr(v))
r = t.ask("frobnicate", ok=False)
if "'frobnicate' is not a command" not in r["error"]:
    fail(r["error"])
# a NUL in a line (line noise) is refused by its place, not echoed cut short at it, as text and
# as JSON; the box goes on
if t.text("frob\0nicate") != [
        "error: control byte 0x00 at column 5 refused (a command is printable text)"]:
    fail("NUL in a line")
r = t.ask("status\x1b[2J", ok=False)
if r["error"] != "control byte 0x1b at column 7 refused (a command is printable text)":
    fail("escape in a line: " + r["error"])
# a key that is not there is one line, as text and as JSON, and the box goes on (it once ended
# the appliance with status 1)
if t.text("config get nosuch") != [
        "error: 'nosuch' is not a configuration key (config list shows them)"]:
    fail("config get nosuch")
for command in ("config get nosuch", "config reset nosuch", "config set nosuch 1"):
    r = t.ask(command, ok=False)
    if "'nosuch' is not a configuration key" not in r["error"]:
        fail(command + ": " + r["error"])
if t.ask("status")["state"] != "idle":
    fail("the box is not idle after the unknown keys")
for command, why in [("confirm", "not waiting for a person"), ("cancel", "nothing to cancel"),
                     ("camera plane", "not calibrated yet"), ("capture", "not waiting"),
                     ("last", "no cycle has completed yet"), ("revert", "no cycle")]:
    r = t.ask(command, ok=False)
    if why not in r["error"]:
        fail(f"{command}: {r['error']}")
print("refusals: over-long line, unknown command, commands out of place")

# Every command the console lists, with an unknown argument, an over-long one (inside the line's
# 256 bytes) and, where it takes some, none: one reply line each, and the box still up, idle and
# not started (a "quit now" once stopped the box; a "press twice" would start a cycle). Commands
# that act are not sent bare: the console's own table says which (help's "acts").
tried = 0
commands = t.ask("help")["commands"]
acting = {e["command"].split()[0] for e in commands if e["acts"]}
if not {"start", "quit", "config"} <= acting or "status" in acting:
    fail("help's acting rows: %s" % sorted(e["command"] for e in commands if e["acts"]))
for entry in commands:
    usage = entry["command"].split()
    name = []
    for word in usage:
        if not word[0].islower():
            break
        name.append(word)
    name = " ".join(name)
    trials = [name + " bogus-word", name + " " + "z" * 200]
    if len(usage) > len(name.split()) and not entry["acts"]:
        trials.append(name)
    for command in trials:
        t.send(command + " --json\r")
        while True:
            line = t.line(60)
            if line is None:
                fail("no reply to " + command[:60] + " (the box " +
                     ("ended" if box.poll() is not None else "is silent") + ")")
            if not line.startswith("notice: "):
                break
        try:
            json.loads(line)
        except ValueError:
            fail(f"{command[:60]}: not one JSON line: {line!r}")
        # The next line is the status's own reply: a second line from the command would be read
        # here instead.
        try:
            s = t.ask("status")
        except ValueError:
            fail(f"{command[:60]}: more than one line")
        if s.get("state") != "idle" or s.get("cycle") != 0:
            fail(f"after {command[:60]}: {s}")
        tried += 1
t.ask("web password --clear")  # its argument is free text: the trials above set one
print(f"bad arguments: {tried} lines, one reply each, the box idle")

# the camera's set-up from the console, one capture per view
t.ask("camera calibrate")
views = []
for v in range(8):
    # status, not the notice: a reconnected terminal did not see it
    t.wait_state("setup-camera", waiting="hold the board in view, press")
    t.ask("capture")
    views.append(t.wait_notice(f"view {v + 1}/8: "))
    if v == 3:
        # the person's terminal goes away mid set-up and comes back
        t.close()
        t = Terminal()
        s = t.ask("status")
        if s["state"] != "setup-camera" or not s["setup_coverage"] > 0:
            fail(f"after reconnecting: {s}")
coverage = int(views[-1].split(" corners, ")[1].split(" %")[0])
if coverage < 30 or int(views[0].split(" corners, ")[1].split(" %")[0]) >= coverage:
    fail("coverage did not grow: " + repr(views))
t.wait_notice("camera calibrated from 8 views, RMS ")
t.wait_notice("waiting: lay the board")
t.ask("capture")
t.wait_notice("bed plane from")
t.wait_state("idle")
print("set-up:", views[-1], "| reconnected mid set-up")

# a cycle started and confirmed from the console
t.ask("start")
t.wait_notice("waiting: clear the bed")
r = t.ask("capture", ok=False)
if "no set-up view" not in r["error"]:
    fail(r["error"])
t.ask("confirm")
t.wait_notice("waiting: press: apply, hold: cancel")
if t.ask("status")["state"] != "review":
    fail("not in review")
t.ask("confirm")
t.wait_notice("waiting: clear the bed")  # the verification's sheet
t.ask("confirm")
t.wait_state("idle", completed=1)
last = t.ask("last")
if last["cycle"] != 1 or not last["applied"] or not (last["after"]["rms_mm"] < 0.05):
    fail(f"last: {last}")
# passes are a delta printer's (test_appliance reads them): a router's cycle has none
if "passes" in last:
    fail(f"last: a router's cycle with passes: {last}")
# A job through the correction the box keeps, placed at its work zero: the controller's (grbl's
# $#, G54 at machine -300, -300 in this scenario, asked when no zero is given) or one given; a
# compensated job is not taken again.
with open(os.path.join(data, "job-part.nc"), "w") as f:
    f.write("G21 G90\nG0 X0 Y0 Z5\nG1 X100 Y50 F600\nG99 G81 X20 Y20 Z-2 R1 F300\nG80\nM2\n")
# No work zero given: grbl is asked for its offsets, as with `controller`.
t.ask("compensate job-part.nc")
done = t.wait_notice("compensate: job-part-compensated.nc: ")
if ("the controller's work offsets ($#: G54=-300.000,-300.000" not in done or
        "G54 zero at machine X-300.000 Y-300.000 mm" not in done or "1 holes placed" not in done):
    fail("compensate from the controller: " + done)
out = open(os.path.join(data, "job-part-compensated.nc")).read().splitlines()
# The G81 written out for grbl: its F on the hole's first line, then the plunge.
if not out[0].startswith("; calbox: compensated through result fnv1a64:") or not any(
        line.startswith("G0 X") and line.endswith(" F300") for line in out) or not any(
        line == "G1 Z-2" for line in out):
    fail("the compensated job: " + repr(out[:12]))
t.ask("compensate job-part.nc -250,-200")
if "G54 zero at machine X-250.000 Y-200.000 mm" not in t.wait_notice("compensate: job-part-compensated.nc: "):
    fail("compensate at a given work zero")
t.ask("compensate job-part-compensated.nc measured")
if "already compensated" not in t.wait_notice("compensate: "):
    fail("a compensated job taken again")
log = t.ask("log 5")["log"]
if len(log) != 5:
    fail("log 5")
t.ask("start")
t.wait_notice("waiting: clear the bed")
t.ask("cancel")
t.wait_state("idle")
t.ask("revert")
t.ask("config reset")
if t.ask("config get setup.calibration_views")["value"] != "12":
    fail("config reset did not reset every key")
if "calibration_views = 8" not in open(saved).read():
    fail("config reset touched the saved file")
t.send("quit\n")  # its reply may be lost with the pty as the box exits
box.wait(60)
if box.returncode != 0:
    fail(f"exit {box.returncode}")
print(f"cycle from the console: measured after {last['after']['rms_mm']:.4f} mm RMS; cancel, revert, quit")
