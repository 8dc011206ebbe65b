#!/usr/bin/python3
"""OctoPrint's application-keys flow started from the console, as an owner sets a box up.

calbox run --console pty on the sim board with a Marlin printer behind the twin's OctoPrint and
link.key_file set by the configuration: `link key owner` is answered at once, the twin's
OctoPrint grants the key a second later (as if the owner clicked Allow), and a notice says where
the key went. The file holds the host's key, mode 0600; the key is never in the console's lines
or the log. A second `link key` on a machine file whose link is serial is refused.
"""
import json
import os
import select
import stat
import subprocess
import sys
import tempfile
import termios
import time
import tty

calbox, top = sys.argv[1], sys.argv[2]
work = tempfile.mkdtemp(prefix="calbox-link-key-")
data = os.path.join(work, "box")
key_file = os.path.join(work, "octoprint.key")
config = os.path.join(work, "calbox.toml")
with open(config, "w") as f:
    f.write('[link]\nkey_file = "%s"\n' % key_file)
err_path = os.path.join(work, "run.err")


def start(scenario, config_file, name=None):
    global data
    data = os.path.join(work, name or os.path.basename(scenario))  # each box its own console link
    err = open(err_path, "w")
    return subprocess.Popen(
        [calbox, "run", "--board", "sim", "--console", "pty", "--scenario", scenario,
         "--config", config_file, "--data", data],
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err)


def fail(why):
    print("FAIL:", why)
    try:
        print(open(err_path).read()[-3000:])
    except OSError:
        pass
    box.kill()
    sys.exit(1)


def terminal():
    link = os.path.join(data, "console")
    for _ in range(300):
        if os.path.islink(link):
            break
        time.sleep(0.1)
    else:
        fail("no console link")
    fd = os.open(link, os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    termios.tcflush(fd, termios.TCIFLUSH)
    return fd


def lines_until(fd, wanted, timeout_s):
    """Every line the console says until one starts with `wanted`."""
    buffer, seen = b"", []
    end = time.time() + timeout_s
    while time.time() < end:
        r, _, _ = select.select([fd], [], [], max(0.0, end - time.time()))
        if r:
            buffer += os.read(fd, 4096)
        while b"\n" in buffer:
            text, buffer = buffer.split(b"\n", 1)
            line = text.decode().rstrip("\r")
            seen.append(line)
            if line.startswith(wanted):
                return seen
    fail("never saw %r; saw %r" % (wanted, seen))


box = start(os.path.join(top, "examples/octoprint_delta.toml"), config)
fd = terminal()
os.write(fd, b"link key owner --json\r")
seen = lines_until(fd, "{", 30)
reply = json.loads(seen[-1])
if not reply["ok"] or not reply["asked"].startswith("http://127.0.0.1:"):
    fail("link key: %r" % reply)
seen += lines_until(fd, "notice: link key: ", 30)
if seen[-1] != "notice: link key: OctoPrint's key for calbox is in %s; the box uses it from " \
        "its next start" % key_file:
    fail("the notice: %r" % seen[-1])
key = open(os.path.join(data, "twin-host.key")).read().strip()
if open(key_file).read() != key + "\n":
    fail("the key file does not hold the host's key")
if stat.S_IMODE(os.stat(key_file).st_mode) != 0o600:
    fail("the key file's mode is %o" % stat.S_IMODE(os.stat(key_file).st_mode))
if any(key in line for line in seen):
    fail("the key was shown on the console")
os.close(fd)
box.terminate()
if box.wait(20) != 0:
    fail("SIGTERM: exit %d" % box.returncode)
if key in open(err_path).read():
    fail("the key is in the log")

# A key_file whose folder is not there yet: the box starts all the same (the folder is needed only
# when a key is kept); asked then, the key cannot be kept and the console says why.
later_key = os.path.join(work, "keys", "octoprint.key")
later_config = os.path.join(work, "later.toml")
with open(later_config, "w") as f:
    f.write('[link]\nkey_file = "%s"\n' % later_key)
box = start(os.path.join(top, "examples/octoprint_delta.toml"), later_config, "later")
fd = terminal()
os.write(fd, b"link key owner --json\r")
seen = lines_until(fd, "{", 30)
if not json.loads(seen[-1])["ok"]:
    fail("link key with the key's folder missing: %r" % seen[-1])
seen += lines_until(fd, "notice: link key: ", 30)
if not seen[-1].startswith("notice: link key: OctoPrint gave a key, but it could not be kept: ") \
        or os.path.join(work, "keys") not in seen[-1]:
    fail("the notice for a missing folder: %r" % seen[-1])
if os.path.exists(later_key):
    fail("a key was written where its folder is missing")
os.close(fd)
box.terminate()
if box.wait(20) != 0:
    fail("SIGTERM with the key's folder missing: exit %d" % box.returncode)

# A serial printer: nothing to ask.
box = start(os.path.join(top, "tests/scenarios/delta_cycle_small.toml"), config)
fd = terminal()
os.write(fd, b"link key --json\r")
reply = json.loads(lines_until(fd, "{", 30)[-1])
if reply["ok"] or "keys are asked of OctoPrint; this machine's link is serial" not in reply["error"]:
    fail("link key on a serial printer: %r" % reply)
os.close(fd)
box.terminate()
box.wait(20)
print("link key: OctoPrint's key kept in %s (0600), never shown; refused for a serial link" % key_file)
