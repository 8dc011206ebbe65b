#!/usr/bin/python3
"""The page over https with the box's own certificate: made on the first start in the data
directory (the key readable by its owner only), its SHA-256 fingerprint the same in the log, in
the console's `web tls` and as openssl reads it from the file; the page trusted through that
certificate alone; the display's network screen shown; a client that connects and never begins
its handshake closed at the 15 s idle limit; the next start serves the same certificate, and says
nothing new of it. Usage: web_tls.py CALBOX SOURCE_DIR"""
import json
import os
import re
import select
import ssl
import stat
import subprocess
import sys
import tempfile
import time
import tty
import urllib.request

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import Run  # noqa: E402

calbox, top = sys.argv[1], sys.argv[2]
work = tempfile.mkdtemp(prefix="calbox-webtls-")
run = Run(work)
data = os.path.join(work, "data")
os.makedirs(data)


def start():
    err = open(os.path.join(work, "box.err"), "w")
    box = subprocess.Popen(
        [calbox, "run", "--board", "sim", "--scenario",
         os.path.join(top, "tests/scenarios/delta_cycle_small.toml"), "--data", data,
         "--web", "127.0.0.1:0", "--web-tls", "127.0.0.1:0", "--console", "pty"],
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err)
    run.children.append(box)
    page = run.wait_for("the https page in the log", lambda: re.search(
        r"web: the page at https://127\.0\.0\.1:(\d+)/ \(certificate 127\.0\.0\.1, SHA-256 "
        r"([0-9A-F:]{95})\)", run.log()), 20, box)
    run.wait_for("the console", lambda: os.path.islink(os.path.join(data, "console")), 20, box)
    return box, int(page.group(1)), page.group(2)


def console(box, line):
    """The JSON reply to one console line."""
    fd = os.open(os.path.join(data, "console"), os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    os.write(fd, (line + " --json\r").encode())
    got, give_up = b"", time.monotonic() + 20
    try:
        while time.monotonic() < give_up:
            if select.select([fd], [], [], 0.5)[0]:
                got += os.read(fd, 4096)
            for text in got.decode(errors="replace").split("\n"):
                if text.startswith("{"):
                    return json.loads(text)
            if box.poll() is not None:
                break
    finally:
        os.close(fd)
    run.fail("no reply to %r: %r" % (line, got[-300:]))


def openssl_fingerprint(path):
    out = subprocess.run(["openssl", "x509", "-noout", "-fingerprint", "-sha256", "-in", path],
                         check=True, capture_output=True, text=True).stdout
    return out.strip().split("=", 1)[1]


box, port, logged = start()
silent = __import__("socket").create_connection(("127.0.0.1", port), timeout=30)
silent_since = time.monotonic()
cert, key = os.path.join(data, "web-tls.crt"), os.path.join(data, "web-tls.key")
if stat.S_IMODE(os.stat(key).st_mode) != 0o600:
    run.fail("the key is mode %o, not 600" % stat.S_IMODE(os.stat(key).st_mode))
made = openssl_fingerprint(cert)
if logged != made:
    run.fail("the log's fingerprint %s is not openssl's %s" % (logged, made))
if "certificate made anew" not in run.log():
    run.fail("the first start did not say it made the certificate")
display = os.path.join(data, "display")
shown_before = len(os.listdir(display))
reply = console(box, "web tls")
if not reply["ok"] or reply["sha256"] != made or reply["port"] != port or not reply["self_signed"]:
    run.fail("web tls: %s" % reply)
# Trusting that one certificate and nothing else, as a person does who checked the fingerprint.
context = ssl.create_default_context(cafile=cert)
with urllib.request.urlopen("https://127.0.0.1:%d/api/status" % port, context=context,
                            timeout=10) as r:
    if r.status != 200 or json.loads(r.read())["state"] != "idle":
        run.fail("the page over https: %d" % r.status)
print("ok   the box's own certificate: key 0600, SHA-256 %s in the log, `web tls` and openssl"
      % made)
# The display: the network screen, one more than before it was asked for.
run.wait_for("the network screen", lambda: len(os.listdir(display)) == shown_before + 1, 5, box)
# The silent client: closed at the idle limit although it never began TLS.
silent.settimeout(30)
try:
    closed = silent.recv(1) == b""
except ConnectionResetError:
    closed = True
held_s = time.monotonic() - silent_since
if not closed or not 14 <= held_s <= 17.5:
    run.fail("a client that never began its handshake was let go after %.1f s" % held_s)
print("ok   a client that never began its handshake: closed after %.1f s (the idle limit 15 s)"
      % held_s)
box.terminate()
if box.wait(10) != 0:
    run.fail("the box exited %d on SIGTERM" % box.returncode)

box, port, again = start()
if again != made or openssl_fingerprint(cert) != made or "made anew" in run.log():
    run.fail("the next start: %s, not the same certificate %s" % (again, made))
print("ok   the next start serves the same certificate, without a word of it")
run.stop_all()
print("web tls: all checks pass")
