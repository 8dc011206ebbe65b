#!/usr/bin/python3
"""The box's web page and MQTT refuse what they must, each with its status and a clear message,
while a cycle runs and without disturbing it: a body too large, headers too large, a request that
does not parse, paths that climb out of the records, malformed JSON, a configuration value out of
range, no password, a wrong one (then a wait), a flood of requests, too many connections, a
method or content type not served. A broker that refuses the box at the start is one log line,
and the one that takes it in its place is reached at the back-off's next try; its going is one
line more. The cycle then completes
and meets the delta goal as if nobody had knocked. Usage: web_refusals.py CALBOX SOURCE_DIR"""
import http.client
import json
import os
import re
import select
import socket
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import (PASSWORD, TLS, Run, connect, free_port, get_json, http_connection,  # noqa: E402
                    password_hash, request)

calbox, top = sys.argv[1], sys.argv[2]
work = tempfile.mkdtemp(prefix="calbox-webno-")
run = Run(work)
# At the start a broker that refuses the box (no anonymous clients); later one that takes it.
broker_port = free_port()
conf = os.path.join(work, "mosquitto.conf")


def start_broker(anonymous):
    """A broker on broker_port, listening before this returns (a box started before it would
    log that it cannot reach it, not its refusal); None if it could not take the port."""
    with open(conf, "w") as f:
        f.write("listener %d 127.0.0.1\nallow_anonymous %s\npersistence false\n" % (
            broker_port, "true" if anonymous else "false"))
    b = subprocess.Popen(["/usr/sbin/mosquitto", "-c", conf], stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL)
    run.children.append(b)
    give_up = time.monotonic() + 10
    while time.monotonic() < give_up and b.poll() is None:
        try:
            socket.create_connection(("127.0.0.1", broker_port), timeout=0.2).close()
            return b
        except OSError:
            time.sleep(0.05)
    b.kill()
    b.wait()
    return None


# The port free_port() found may be taken by another test before the broker binds it: another.
for attempt in range(3):
    refusing = start_broker(False)
    if refusing:
        break
    broker_port = free_port()
else:
    run.fail("no broker could listen")
config = '[web]\npassword = "%s"\n' % password_hash(PASSWORD)
box, url = run.box(calbox, top, os.path.join(work, "data"),
                   ["--mqtt", "127.0.0.1:%d" % broker_port, "--operator"], config)
port = int(url.rsplit(":", 1)[1])


def expect(what, got, status, message=None):
    code, headers, body = got
    if code != status:
        run.fail("%s: %d, not %d (%s)" % (what, code, status, body[:200]))
    if message is not None:
        error = json.loads(body)["error"]
        if not re.search(message, error):
            run.fail("%s: %r does not say %r" % (what, error, message))
    return headers


def raw(data, source="127.0.0.1", read=True):
    """What the server answers to bytes sent as they are (no client tidies them)."""
    s = connect(port, source)
    s.sendall(data)
    if not read:
        return s
    out = b""
    while True:
        chunk = s.recv(65536)
        if not chunk:
            break
        out += chunk
    s.close()
    return out


def from_peer(source, method, path, body=None, headers=None):
    c = http_connection(port, source, timeout=10)
    c.request(method, path, body=body, headers=headers or {})
    r = c.getresponse()
    out = (r.status, r.headers, r.read())
    c.close()
    return out


if TLS:
    # The plain port: a redirect to the same path on https; a password sent there refused, not
    # checked (no wrong-password count), whatever it is.
    plain = "http://127.0.0.1:%d" % run.plain_port
    c = http.client.HTTPConnection("127.0.0.1", run.plain_port, timeout=10)
    c.request("GET", "/api/status?x=1")
    r = c.getresponse()
    r.read()
    if r.status != 308 or r.headers["Location"] != url + "/api/status?x=1":
        run.fail("the plain port answered %d, Location %s" % (r.status, r.headers["Location"]))
    for attempt in range(6):
        expect("the password over plain http", request(plain + "/api/action", "POST",
                                                       {"action": "start"}, password=PASSWORD),
               403, "not taken over plain http")
    c = http.client.HTTPConnection("127.0.0.1", run.plain_port, timeout=10)
    c.request("GET", "/events", headers={"Connection": "Upgrade", "Upgrade": "websocket",
                                         "Sec-WebSocket-Version": "13",
                                         "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ=="})
    if c.getresponse().status != 403:
        run.fail("the plain port took a websocket")
    print("ok   TLS: the plain port redirects (308 to the same path), refuses the password (403) "
          "and websockets")
expect("start", request(url + "/api/action", "POST", {"action": "start"}, password=PASSWORD), 200)
run.wait_for("the cycle under way", lambda: get_json(url + "/api/status")["state"] != "idle", 10, box)

# While it runs, everything that must be refused.
expect("a body past 64 KiB", request(url + "/api/config", "POST", b"{" + b" " * 100000 + b"}",
                                     password=PASSWORD), 413)
if not raw(b"GET / HTTP/1.1\r\nHost: x\r\nX-Big: " + b"a" * 20000 + b"\r\n\r\n").startswith(
        b"HTTP/1.1 431"):
    run.fail("headers past 16 KiB were not refused with 431")
if not raw(b"NOT HTTP AT ALL\r\n\r\n").startswith(b"HTTP/1.1 400"):
    run.fail("a request that does not parse was not refused with 400")
for climb in ("/records/../calbox.toml", "/records/..%2Fcalbox.toml", "/records/%2e%2e/calbox.toml",
              "/records/calbox.toml", "/records/.hidden", "/records//etc/passwd"):
    expect("GET " + climb, from_peer("127.0.0.1", "GET", climb), 403, "not a record")
expect("a record not there", request(url + "/records/cycle-9999-result.json"), 404)
# The files other modes keep beside the records are not this delta box's (each mode declares its
# own, CycleMode::kept_files).
for other in ("/records/galvo-table.json", "/records/planar-result.json"):
    expect("GET " + other, from_peer("127.0.0.1", "GET", other), 403, "not a record")
expect("malformed JSON", request(url + "/api/config", "POST", b'{"key": "cycle.', password=PASSWORD),
       400, "malformed JSON")
expect("JSON not an object", request(url + "/api/action", "POST", b'["start"]', password=PASSWORD),
       400, "object")
expect("an action not served", request(url + "/api/action", "POST", {"action": "format"},
                                       password=PASSWORD), 400, "one of start")
# JSON's value() throws on a key of another type: the action is read only where it is a string.
expect("an action that is not a string", request(url + "/api/action", "POST", {"action": 5},
                                                 password=PASSWORD), 400, "one of start")
expect("a job name that climbs", request(url + "/api/action", "POST",
                                        {"action": "compensate", "job": "../calbox.toml"},
                                        password=PASSWORD), 400, "compensate")
expect("a job through no correction", request(url + "/api/action", "POST",
                                              {"action": "compensate", "job": "job-part.nc",
                                               "work_zero": "measured"},
                                              password=PASSWORD), 409, "no correction in force")
expect("a value out of range", request(url + "/api/config", "POST",
                                       {"key": "cycle.frames_per_capture", "value": "99"},
                                       password=PASSWORD), 409, r"1 to 16")
expect("an unknown key", request(url + "/api/config", "POST", {"key": "cycle.nothing", "value": "1"},
                                 password=PASSWORD), 409, "not a configuration key")
expect("a value with a newline", request(url + "/api/config", "POST",
                                         {"key": "console.device", "value": "a\nstart"},
                                         password=PASSWORD), 400, "one line")
expect("the password's hash through the page", request(url + "/api/config", "POST",
                                                       {"key": "web.password", "value": ""},
                                                       password=PASSWORD), 403, "console")
expect("start while busy", request(url + "/api/action", "POST", {"action": "start"},
                                   password=PASSWORD), 409, "busy")
expect("no password", request(url + "/api/action", "POST", {"action": "cancel"}), 401, "password")
expect("a form, not JSON", request(url + "/api/action", "POST", b"action=cancel",
                                   headers={"Content-Type": "application/x-www-form-urlencoded"},
                                   password=PASSWORD), 415)
expect("DELETE", request(url + "/", "DELETE"), 405)
expect("nothing there", request(url + "/nothing"), 404)
if "web.password" in get_json(url + "/api/config")["config"]:
    run.fail("the page's configuration shows the password's hash")

# Wrong passwords from one client: five refused, then that client waits, the right one too.
bad = {"Content-Type": "application/json",
       "Authorization": "Basic " + __import__("base64").b64encode(b"calbox:guess").decode()}
for i in range(5):
    expect("wrong password %d" % (i + 1), from_peer("127.0.0.2", "POST", "/api/action",
                                                    b'{"action": "cancel"}', bad), 401, "wrong")
good = dict(bad, Authorization="Basic " + __import__("base64").b64encode(
    ("calbox:" + PASSWORD).encode()).decode())
headers = expect("the right password during the wait",
                 from_peer("127.0.0.2", "POST", "/api/action", b'{"action": "cancel"}', good), 429,
                 "wrong passwords")
if headers["Retry-After"] != "30":
    run.fail("no Retry-After on the wait")

# A flood from one client: past its burst, refused with 429; other clients are still served.
# It may take 60 at once and 20 a second after: on a loaded machine the flood is slower and more
# of it is served, so what may pass is worked out from how long it took.
flood_began = time.monotonic()
# One connection kept alive (a new one each, over TLS, would pace the flood by its handshakes).
flooder = http_connection(port, "127.0.0.3", timeout=10)
codes = []
for _ in range(150):
    flooder.request("GET", "/api/status")
    reply = flooder.getresponse()
    reply.read()
    codes.append(reply.status)
flooder.close()
flood_s = time.monotonic() - flood_began
may_pass = 60 + 20 * flood_s + 1
if codes[0] != 200 or codes.count(429) == 0 or codes.count(200) > may_pass:
    run.fail("a flood of 150 in %.1f s: %d served, %d refused (at most %.0f may pass)" % (
        flood_s, codes.count(200), codes.count(429), may_pass))
expect("another client during the flood", request(url + "/api/status"), 200)

# Too many connections: past 32 open, the next is told 503 and closed. Over TLS the places are
# held by clients that never begin their handshake, and the refusal comes once the 33rd's is done.
# A place an earlier client left may still be held while its connection's thread ends (the
# flooder's, on a loaded machine): a held one refused for it is seen (answered, or over TLS closed
# at the refusal's 2 s) and another opened, so that the 33rd meets exactly 32.
held, replaced = [], 0
give_up = time.monotonic() + 20
while len(held) < 32:
    if time.monotonic() > give_up:
        run.fail("32 connections could not be held: %d refused in 20 s" % replaced)
    held += [connect(port, "127.0.0.4", handshake=False) for _ in range(32 - len(held))]
    time.sleep(2.3 if TLS else 0.3)
    for s in select.select(held, [], [], 0)[0]:
        held.remove(s)
        s.close()
        replaced += 1
if replaced:
    print("note %d of the held connections refused while an earlier client's place was freed; "
          "opened again" % replaced)
# Connection: close, so that a 33rd served instead of refused says so rather than waiting.
extra = raw(b"GET / HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", source="127.0.0.4")
for s in held:
    s.close()
if not extra.startswith(b"HTTP/1.1 503"):
    run.fail("the 33rd connection was not refused with 503: %r" % extra[:40])
run.wait_for("the page serving again after the connections closed",
             lambda: request(url + "/api/status")[0] == 200, 10, box)

if TLS:
    # Over https the refusals and the limits are what this run is for; the broker's part and the
    # cycle's end are the plain run's (the same box, the same code above the connection).
    run.stop_all()
    print("refusals over https: 413 431 400 403x6 404 409x4 401 415 405 429 503 all as expected; "
          "a flood refused %d of 150" % codes.count(429))
    sys.exit(0)

# The refusing broker goes, one that takes the box comes: reached at the back-off's next try.
run.wait_for("the refusal logged", lambda: "mqtt: the broker refused the box" in run.log(), 15, box)
refusing.kill()
refusing.wait()
broker = start_broker(True)
if not broker:
    run.fail("the second broker could not listen on port %d" % broker_port)
run.wait_for("the box connected to the late broker", lambda: "mqtt: connected" in run.log(), 90, box)
broker.kill()
broker.wait()
run.wait_for("the broker's going logged", lambda: "mqtt: the broker went" in run.log(), 15, box)

# The cycle went on through all of it.
run.wait_for("the review", lambda: get_json(url + "/api/status")["state"] == "review", 120, box)
expect("confirm", request(url + "/api/action", "POST", {"action": "confirm"}, password=PASSWORD), 200)
run.wait_for("the cycle completed", lambda: get_json(url + "/api/status")["completed"] == 1, 120, box)
last = get_json(url + "/api/status")["last"]
if last["result"] != "applied" or not last["after"]["rms_mm"] <= 0.01 or not last["after"]["max_mm"] <= 0.03:
    run.fail("the cycle under the knocking: %s" % last)
log = run.log()
troubles = re.findall(r"mqtt: (cannot reach|the broker refused|the broker went)", log)
if troubles != ["the broker refused", "the broker went"]:
    run.fail("the broker's troubles were told as %s, not once each" % troubles)
run.stop_all()
print("refusals: 413 431 400 403x6 404 409x4 401 415 405 429 503 all as expected; a flood refused "
      "%d of 150; the cycle after them: %.4f mm RMS, %.4f mm worst" % (
          codes.count(429), last["after"]["rms_mm"], last["after"]["max_mm"]))
