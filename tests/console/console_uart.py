#!/usr/bin/python3
"""The console on a UART that comes and goes, as a USB serial adapter does.

The box's console.device is a path (here DIR/uart, a link to a pseudo-terminal's far end, as
udev's /dev/serial/by-id links point at /dev/ttyUSB0): not there when the box starts, then
plugged in, unplugged (the pseudo-terminal closed, the link gone) and plugged in again under a
new device behind the same path. The box answers on it each time it is there and runs on while
it is not.
"""
import json
import os
import select
import subprocess
import sys
import tempfile
import time
import tty

calbox, top = sys.argv[1], sys.argv[2]
work = tempfile.mkdtemp(prefix="calbox-uart-")
data = os.path.join(work, "box")
uart = os.path.join(work, "uart")
err_path = os.path.join(work, "run.err")


def fail(why):
    print("FAIL:", why)
    try:
        print(open(err_path).read()[-3000:])
    except OSError:
        pass
    box.kill()
    sys.exit(1)


def plug_in():
    master, slave = os.openpty()
    tty.setraw(master)
    # The near end stays open too, so that the far end does not read as hung up before the box
    # has opened it; the box opens it by the path.
    os.symlink(os.ttyname(slave), uart)
    return master, slave


def unplug(device):
    os.unlink(uart)
    for fd in device:
        os.close(fd)


def ask(device, command, timeout_s=10):
    master = device[0]
    os.write(master, (command + " --json\r").encode())
    buffer = b""
    end = time.time() + timeout_s
    while True:
        while b"\n" in buffer:
            line, buffer = buffer.split(b"\n", 1)
            text = line.decode().strip()
            if text.startswith("{"):
                return json.loads(text)
        left = end - time.time()
        if left <= 0 or box.poll() is not None:
            return None
        r, _, _ = select.select([master], [], [], min(left, 0.5))
        if r:
            try:
                buffer += os.read(master, 4096)
            except OSError:
                return None
        elif not buffer:
            # The box may not have opened the device yet: say it again once it has.
            os.write(master, (command + " --json\r").encode())


def log_has(text, timeout_s=10):
    end = time.time() + timeout_s
    while time.time() < end:
        if text in open(err_path).read():
            return True
        time.sleep(0.1)
    return False


err = open(err_path, "w")
box = subprocess.Popen(
    [calbox, "run", "--board", "sim", "--console", uart, "--operator-hands",
     "--scenario", os.path.join(top, "tests/scenarios/planar_small.toml"), "--data", data],
    stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err)

# Not there at the start: the box says so and runs on.
if not log_has(uart + " is not there"):
    fail("the missing UART was not told")
if box.poll() is not None:
    fail("the box stopped without its console")

device = plug_in()
reply = ask(device, "status")
if reply is None or reply.get("state") != "idle":
    fail("no status after plugging in: %r" % (reply,))
print("plugged in: status answered")

# Unplugged: the box tells it and runs on; nothing it says is lost to a crash.
unplug(device)
if not log_has("opened again when it is back"):
    fail("the unplugged UART was not told")
time.sleep(1.5)  # a few tries at a missing device
if box.poll() is not None:
    fail("the box stopped when the console went")

# Plugged in again (another device behind the same path): the box answers there.
device = plug_in()
reply = ask(device, "config get cycle.long_press_ms")
if reply is None or reply.get("value") != "1500":
    fail("no reply after plugging in again: %r" % (reply,))
if not log_has("console: back"):
    fail("the reconnection was not logged")
print("plugged in again: config get answered")

ask(device, "quit")
try:
    box.wait(timeout=60)
except subprocess.TimeoutExpired:
    fail("the box did not quit")
if box.returncode != 0:
    fail("exit status %d" % box.returncode)
print("PASS")
