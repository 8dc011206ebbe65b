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
COMMAND_TIMEOUT_S = 5  # linuxcncrsh's wait for the task's receipt while the test homes
# (its man page names the setting set_timeout; 2.9's linuxcncrsh knows it as timeout)


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
    # Each joint homed where it stands (LinuxCNC's setting for a machine without home
    # switches): the simulated switches' search is motion, and a busy machine starves the
    # servo thread that makes it (a fresh clone's CI took over a minute to home).
    ini = re.sub(r"(?m)^HOME_SEARCH_VEL = .*$", "HOME_SEARCH_VEL = 0", ini)
    ini = re.sub(r"(?m)^HOME_LATCH_VEL = .*$", "HOME_LATCH_VEL = 0", ini)
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

    def ask(self, line, expect, wait_s=60):
        """Sends a line and returns the first reply starting with expect. Every wait is
        bounded, and one that runs out says which line it was and how long it waited."""
        self.sent.add(line)
        self.sock.sendall((line + "\r\n").encode())
        started = time.time()
        while True:
            while b"\n" in self.buffer:
                got, self.buffer = self.buffer.split(b"\n", 1)
                got = got.decode().strip("\r")
                if got not in self.sent and got.upper().startswith(expect):
                    return got
            left = started + wait_s - time.time()
            if left <= 0:
                raise RuntimeError("linuxcncrsh: no %s to %r in %d s" % (expect, line, wait_s))
            self.sock.settimeout(left)
            try:
                more = self.sock.recv(4096)
            except socket.timeout:
                continue
            if not more:
                raise RuntimeError("linuxcncrsh closed the connection after %r" % line)
            self.buffer += more


def start(work, port):
    fifo = os.path.join(work, "rtapi")
    os.mkdir(fifo)
    os.chmod(fifo, 0o1777)
    # As root, LinuxCNC's rtapi_app runs its non-realtime threads as a fallback user.
    env = dict(os.environ, RTAPI_UID="65534", RTAPI_FIFO_PATH=os.path.join(fifo, "fifo"))
    # LinuxCNC writes to its own copy of the descriptor; this process's is closed at once.
    with open(os.path.join(work, "linuxcnc.log"), "w") as log:
        return subprocess.Popen(["linuxcnc", configuration(work, port)], cwd=work, env=env,
                                stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=True)


def until(rsh, command, question, answer, deadline, what):
    """Sends the owner's command and asks for its state until LinuxCNC answers so, or says what
    did not happen, the command's last reply and LinuxCNC's error. The command goes again every
    10 s without the state: a task still starting, or starved by CI's other tests, may not have
    taken it (linuxcncrsh then answers NAK after its timeout)."""
    sent_at, reply = 0.0, ""
    while True:
        if time.time() - sent_at > 10:
            reply = rsh.ask(command, "SET ", wait_s=COMMAND_TIMEOUT_S + 60)
            sent_at = time.time()
        got = rsh.ask(question, question.split()[1].upper())
        if got.upper().startswith(answer):
            return
        if time.time() > deadline:
            task = subprocess.run(["pgrep", "-x", "milltask"], capture_output=True).returncode
            raise RuntimeError("LinuxCNC: %s (%r to %r, then %r; its error: %s; its task, milltask, "
                               "%s)" % (what, reply, command, got, rsh.ask("get error", "ERROR"),
                                        "running" if task == 0 else "not running"))
        time.sleep(0.3)


def home(process, port, log):
    """The owner's steps: the e-stop released, the machine on, every joint homed. Each command's
    state is polled, so a machine slowed by CI's other tests only takes longer, up to the
    deadline."""
    started = time.time()
    deadline = started + 240
    while True:
        try:
            rsh = Rsh(port)
            break
        except OSError:
            if process.poll() is not None or time.time() > deadline:
                raise RuntimeError("LinuxCNC did not start (linuxcnc exited %s)" % process.poll())
            time.sleep(0.5)
    log("linuxcncrsh answered after %.1f s" % (time.time() - started))
    rsh.ask("hello EMC owner 1.0", "HELLO ACK")
    rsh.ask("set verbose on", "SET VERBOSE")  # echoed, as everything until echo is off
    rsh.ask("set echo off", "SET ECHO")
    reply = rsh.ask("set enable EMCTOO", "SET ")
    if not reply.endswith("ACK"):
        raise RuntimeError("linuxcncrsh: 'set enable EMCTOO' -> %r" % reply)
    # linuxcncrsh waits for the task's receipt of each command, and by default for ever: a
    # command the task missed while it was starting left 'set estop off' unanswered in CI. The
    # wait is bounded while this client turns the machine on, and given back (0: LinuxCNC's
    # default) before the box connects: the setting is linuxcncrsh's, for every connection.
    for line in ("set set_wait received", "set timeout %d" % COMMAND_TIMEOUT_S):
        reply = rsh.ask(line, "SET ")
        if not reply.endswith("ACK"):
            raise RuntimeError("linuxcncrsh: %r -> %r" % (line, reply))
    until(rsh, "set estop off", "get estop", "ESTOP OFF", deadline, "the e-stop was not released")
    until(rsh, "set machine on", "get machine", "MACHINE ON", deadline,
          "the machine did not come on")
    until(rsh, "set mode manual", "get mode", "MODE MANUAL", deadline,
          "the mode did not become manual")
    log("the machine on, in manual, after %.1f s" % (time.time() - started))
    until(rsh, "set home -1", "get joint_homed", "JOINT_HOMED YES YES YES", deadline,
          "the mill did not home")
    log("homed after %.1f s" % (time.time() - started))
    # Control is the box's from here: this client gives the wait back and lets go of control.
    reply = rsh.ask("set timeout 0", "SET TIMEOUT")
    if not reply.endswith("ACK"):
        raise RuntimeError("linuxcncrsh: 'set timeout 0' -> %r" % reply)
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
        home(process, port, lambda line: print(line, flush=True))
        run = subprocess.run([sys.argv[1], "-g", "LinuxCncReal", "-v"],
                             env=dict(os.environ, CALBOX_LINUXCNC="127.0.0.1:%d" % port),
                             stdin=subprocess.DEVNULL, timeout=300)
        return run.returncode
    except (RuntimeError, OSError) as e:
        print("FAIL: %s" % e)
        # What the linuxcnc script and its programs said; without a terminal, LinuxCNC keeps
        # its messages in the last two (after an error).
        for path in (os.path.join(work, "linuxcnc.log"),
                     os.path.join(os.path.expanduser("~"), "linuxcnc_print.txt"),
                     os.path.join(os.path.expanduser("~"), "linuxcnc_debug.txt")):
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
