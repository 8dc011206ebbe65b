#!/usr/bin/python3
"""The LinuxCNC link judged by LinuxCNC itself: LinuxCNC's simulated mill (its own sample
configuration, axis_mm.ini, from linuxcnc-uspace) started headless with linuxcncrsh as its
display, turned on and homed as its owner would, and then the link's requests through
LinuxCNC's own linuxcncrsh, task and interpreter (tests/unit/test_linuxcnc_link.cpp, the group
LinuxCncReal): G54 set by MDI and read back, a job run line by line, LinuxCNC's refusals named.

usage: linuxcnc_real.py TEST_BINARY
Exit 77 (skipped) where LinuxCNC is not installed."""
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

SAMPLE = "/usr/share/doc/linuxcnc/examples/sample-configs/sim"


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def configuration(work, port):
    """axis_mm.ini with linuxcncrsh for its display and nothing that needs a screen."""
    ini = open(os.path.join(SAMPLE, "axis", "axis_mm.ini")).read()
    ini = re.sub(r"(?m)^DISPLAY = .*$", "DISPLAY = linuxcncrsh --port %d" % port, ini)
    ini = re.sub(r"(?m)^HALFILE = axis_manualtoolchange.hal\n", "", ini)
    ini = re.sub(r"(?m)^(HALUI|INTRO_GRAPHIC|INTRO_TIME) = ", r"#\1 = ", ini)
    path = os.path.join(work, "mill.ini")
    open(path, "w").write(ini)
    shutil.copy(os.path.realpath(os.path.join(SAMPLE, "sim_mm.tbl")), work)
    return path


class Rsh:
    """A few lines to linuxcncrsh, as the owner's own client would send them."""

    def __init__(self, port):
        # A busy machine (the suite beside it, under ASan) slows LinuxCNC's task to seconds a
        # command.
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=60)
        self.buffer = b""
        self.sent = set()

    def ask(self, line, expect):
        self.sent.add(line)
        self.sock.sendall((line + "\r\n").encode())
        deadline = time.time() + 60
        while time.time() < deadline:
            while b"\n" in self.buffer:
                got, self.buffer = self.buffer.split(b"\n", 1)
                got = got.decode().strip("\r")
                if got not in self.sent and got.upper().startswith(expect):
                    return got
            self.buffer += self.sock.recv(4096)
        raise RuntimeError("linuxcncrsh: no %s to %r" % (expect, line))


def start(work, port):
    fifo = os.path.join(work, "rtapi")
    os.mkdir(fifo)
    os.chmod(fifo, 0o1777)
    # As root, LinuxCNC's rtapi_app runs its non-realtime threads as a fallback user.
    env = dict(os.environ, RTAPI_UID="65534", RTAPI_FIFO_PATH=os.path.join(fifo, "fifo"))
    return subprocess.Popen(["linuxcnc", configuration(work, port)], cwd=work, env=env,
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)


def home(process, port):
    """The owner's steps: the e-stop released, the machine on, every joint homed. Each command
    waits until LinuxCNC has done it (set_wait done), and homing is asked again if a busy
    machine (CI's other tests beside it) let it drop."""
    deadline = time.time() + 180
    while True:
        try:
            rsh = Rsh(port)
            break
        except OSError:
            if process.poll() is not None or time.time() > deadline:
                raise RuntimeError("LinuxCNC did not start (linuxcnc exited %s)" % process.poll())
            time.sleep(0.5)
    rsh.ask("hello EMC owner 1.0", "HELLO ACK")
    rsh.ask("set verbose on", "SET VERBOSE")  # echoed, as everything until echo is off
    rsh.ask("set echo off", "SET ECHO")
    for line in ("set enable EMCTOO", "set set_wait done", "set estop off", "set machine on"):
        reply = rsh.ask(line, "SET ")
        if not reply.endswith("ACK"):
            raise RuntimeError("linuxcncrsh: %r -> %r" % (line, reply))
    while rsh.ask("get machine", "MACHINE") != "MACHINE ON":
        if time.time() > deadline:
            raise RuntimeError("LinuxCNC's machine did not come on")
        time.sleep(0.3)
    asked = 0
    while True:
        if asked == 0 or time.time() - asked > 20:
            for line in ("set mode manual", "set home -1"):
                rsh.ask(line, "SET ")
            asked = time.time()
        if rsh.ask("get joint_homed", "JOINT_HOMED").startswith("JOINT_HOMED YES YES YES"):
            break
        if time.time() > deadline:
            raise RuntimeError("LinuxCNC's mill did not home (%s)" % rsh.ask("get error", "ERROR"))
        time.sleep(0.3)
    # Control is the box's from here: this client lets go of it.
    rsh.ask("set enable off", "SET ENABLE")
    rsh.sock.close()


def stop(process, port):
    try:
        rsh = Rsh(port)
        rsh.ask("hello EMC owner 1.0", "HELLO ACK")
        rsh.ask("set verbose on", "SET VERBOSE")
        rsh.ask("set echo off", "SET ECHO")
        rsh.ask("set enable EMCTOO", "SET ENABLE")
        rsh.sock.sendall(b"shutdown\r\n")
        process.wait(timeout=30)
    except Exception:  # the controller gone or stuck: the linuxcnc script cleans up on TERM
        os.killpg(process.pid, signal.SIGTERM)
        process.wait(timeout=60)
    # Nothing of this LinuxCNC is left for the next one (its shared memory is the machine's).
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def main():
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    if shutil.which("linuxcnc") is None or not os.path.isdir(SAMPLE):
        print("skipped: LinuxCNC (linuxcnc-uspace) is not installed")
        return 77
    work = tempfile.mkdtemp(prefix="calbox-linuxcnc-")
    os.chmod(work, 0o755)  # the fallback user reaches its FIFO's directory through it
    port = free_port()
    process = None
    try:
        process = start(work, port)
        home(process, port)
        run = subprocess.run([sys.argv[1], "-g", "LinuxCncReal", "-v"],
                             env=dict(os.environ, CALBOX_LINUXCNC="127.0.0.1:%d" % port),
                             stdin=subprocess.DEVNULL, timeout=300)
        return run.returncode
    except RuntimeError as e:
        print("FAIL: %s" % e)
        # Without a terminal, LinuxCNC keeps its messages in these (after an error).
        for name in ("linuxcnc_print.txt", "linuxcnc_debug.txt"):
            path = os.path.join(os.path.expanduser("~"), name)
            if os.path.exists(path):
                print("== " + path)
                print(open(path, errors="replace").read()[-2000:])
        return 1
    finally:
        if process is not None:
            stop(process, port)
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
