#!/usr/bin/python3
"""The box on a broker set up as Home Assistant's Mosquitto add-on is: no anonymous access, users
in a password file, an ACL, a TLS listener whose certificate a test CA signed (made here with
openssl). The box logs in over TLS (MQTT 5, and 3.1.1), publishes its discovery, never shows its
password; a start from a user the ACL gives no rights does nothing, one from Home Assistant's user
starts a cycle only where the box allows remote start (and only then is the button discovered); a
wrong password is refused in one line and tried again with back-off; a password file others can
read is not used. Usage: mqtt_login.py CALBOX SOURCE_DIR"""
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time

import paho.mqtt.client as mqtt

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__))))
from common import Run, free_port, sh_in, test_authority  # noqa: E402

calbox, top = sys.argv[1], sys.argv[2]
work = tempfile.mkdtemp(prefix="calbox-mqtt-login-")
run = Run(work)
SECRET = "s3cret-horse-battery"


def sh(*args):
    sh_in(work, *args)


# A test CA and the broker's certificate, for 127.0.0.1.
test_authority(work, "broker")
# Another CA, which did not sign the broker's certificate.
sh("openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2", "-subj",
   "/CN=someone else", "-keyout", "other.key", "-out", "other.crt")

# The add-on's users: the box's login, Home Assistant's, and one that may only read.
sh("mosquitto_passwd", "-c", "-b", "passwd", "calbox", SECRET)
sh("mosquitto_passwd", "-b", "passwd", "homeassistant", "ha-password")
sh("mosquitto_passwd", "-b", "passwd", "viewer", "viewer-password")
with open(os.path.join(work, "acl"), "w") as f:
    f.write("user calbox\ntopic readwrite calbox/#\ntopic readwrite homeassistant/#\n\n"
            "user homeassistant\ntopic readwrite #\n\nuser viewer\ntopic read #\n")
port = free_port()
with open(os.path.join(work, "mosquitto.conf"), "w") as f:
    # Started as root (as CI runs) the broker would drop to its own user, which cannot read this
    # test's private directory: it stays the test's user.
    f.write("user %s\n" % ("root" if os.geteuid() == 0 else os.environ.get("USER", "nobody")))
    f.write("per_listener_settings false\nallow_anonymous false\npassword_file %s/passwd\n"
            "acl_file %s/acl\npersistence false\nconnection_messages true\n"
            "log_dest file %s/broker.log\nlog_type notice\nlog_type information\n"
            "listener %d 127.0.0.1\ncafile %s/ca.crt\ncertfile %s/broker.crt\n"
            "keyfile %s/broker.key\n" % (work, work, work, port, work, work, work))
broker = subprocess.Popen(["/usr/sbin/mosquitto", "-c", os.path.join(work, "mosquitto.conf")],
                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
run.children.append(broker)

messages = []
lock = threading.Lock()


def client(name, user, password):
    c = mqtt.Client(client_id=name)
    c.username_pw_set(user, password)
    c.tls_set(ca_certs=os.path.join(work, "ca.crt"))
    connected = threading.Event()
    c.on_connect = lambda cl, u, flags, rc: connected.set() if rc == 0 else None
    c.connect("127.0.0.1", port)
    c.loop_start()
    if not connected.wait(10):
        run.fail("%s could not log in to the test broker" % user)
    return c


def broker_up():
    try:
        c = client("probe", "homeassistant", "ha-password")
        c.loop_stop()
        c.disconnect()
        return True
    except (OSError, SystemExit):
        return False


run.wait_for("the TLS broker", broker_up, 15)
print("ok   the broker as Home Assistant's add-on: no anonymous access, an ACL, TLS on %d" % port)
ha = client("home-assistant", "homeassistant", "ha-password")


def on_message(cl, userdata, m):
    with lock:
        messages.append((m.topic, m.payload.decode(errors="replace"), bool(m.retain)))


ha.on_message = on_message
ha.subscribe([("homeassistant/#", 1), ("calbox/#", 1)])
viewer = client("viewer", "viewer", "viewer-password")


def seen(predicate):
    with lock:
        return [m for m in messages if predicate(m)]


def password_file(name, text, mode):
    path = os.path.join(work, name)
    with open(path, "w") as f:
        f.write(text + "\n")
    os.chmod(path, mode)
    return path


def start_box(name, mqtt_table):
    run.work = os.path.join(work, name)
    os.makedirs(run.work, exist_ok=True)
    config = "[mqtt]\nbroker = \"127.0.0.1:%d\"\nnode_id = \"%s\"\n%s" % (port, name, mqtt_table)
    return run.box(calbox, top, os.path.join(run.work, "data"), [], config)


def stop_box(box):
    box.send_signal(signal.SIGTERM)
    if box.wait(timeout=30) != 0:
        run.fail("the box did not stop cleanly: %d" % box.returncode)


good = password_file("good.pw", SECRET, 0o600)
tls = "user = \"calbox\"\npassword_file = \"%s\"\ntls = true\nca_file = \"%s/ca.crt\"\n" % (
    good, work)

# 1. MQTT 5 over TLS, remote start on: logged in, discovery with the button; a start from the
# viewer (no rights: the broker drops it) does nothing, one from Home Assistant starts a cycle.
box, url = start_box("box5", tls + "protocol = \"5\"\nremote_start = true\n")
run.wait_for("the login over TLS", lambda: "mqtt: connected to 127.0.0.1:%d" % port in run.log(),
             20, box)
if "logged in as calbox, over TLS; calbox/box5/command starts a cycle" not in run.log():
    run.fail("the log does not say how the box reports")


def box_configs(node):
    return {t for t, p, r in seen(lambda m: m[0].startswith("homeassistant/") and
                                  m[0].endswith("/%s/" % node + m[0].split("/")[-2] + "/config")
                                  and m[1])}


configs = run.wait_for("box5's discovery",
                       lambda: box_configs("box5") if len(box_configs("box5")) >= 6 else None,
                       15, box)
if "homeassistant/button/box5/start/config" not in configs:
    run.fail("remote start on: no start button discovered (%s)" % sorted(configs))
print("ok   MQTT 5 over TLS as calbox: %d discovery configs, the start button among them"
      % len(configs))
viewer.publish("calbox/box5/command", "start", qos=1)
time.sleep(3)
if "mqtt: start" in run.log() or "cycle 1:" in run.log():
    run.fail("a start from a user without rights reached the box")
print("ok   a start from the viewer (no rights) does nothing")
ha.publish("calbox/box5/command", "start", qos=1)
run.wait_for("Home Assistant's start", lambda: "mqtt: start: started" in run.log(), 15, box)
print("ok   a start from Home Assistant's user starts a cycle")
stop_box(box)
if SECRET in run.log():
    run.fail("the password is in the box's log")
print("ok   the password is nowhere in the log")

# 2. MQTT 3.1.1 over TLS, remote start off (the default): reports, offers no button, takes back
# one a former configuration offered, and a start even from Home Assistant does nothing.
with lock:
    messages.clear()
ha.publish("homeassistant/button/box311/start/config", '{"name": "stale"}', qos=1, retain=True)
box, url = start_box("box311", tls)
run.wait_for("the 3.1.1 login", lambda: "mqtt: connected to" in run.log(), 20, box)
if "; remote start off" not in run.log():
    run.fail("the log does not say remote start is off")
run.wait_for("box311's state", lambda: seen(lambda m: m[0] == "calbox/box311/state"), 15, box)
run.wait_for("the stale button taken back", lambda: seen(
    lambda m: m[0] == "homeassistant/button/box311/start/config" and m[1] == ""), 15, box)
ha.publish("calbox/box311/command", "start", qos=1)
time.sleep(3)
if "mqtt: start" in run.log() or "cycle 1:" in run.log():
    run.fail("remote start off, yet a start reached the cycle")
print("ok   MQTT 3.1.1 over TLS, remote start off: no button (a stale one removed), start ignored")
stop_box(box)

# 3. A wrong password: one line, then tries again with back-off (the broker sees few attempts).
bad = password_file("bad.pw", "not-the-password", 0o600)
box, url = start_box("wrong", tls.replace(good, bad))
run.wait_for("the refusal", lambda: "mqtt: the broker refused the box as calbox" in run.log(), 20,
             box)
time.sleep(8)
refusals = run.log().count("mqtt: the broker refused")
log = open(os.path.join(work, "broker.log"), errors="replace").read()
# Mosquitto logs a refused login without the client's id; no other client is refused here.
when = [int(t) for t in re.findall(r"^(\d+): Client <unknown> disconnected, not authori[sz]ed",
                                   log, re.M)]
tries = len(when)
gaps = [b - a for a, b in zip(when, when[1:])]
if refusals != 1:
    run.fail("a wrong password told %d times (once wanted)" % refusals)
if not 2 <= tries <= 5 or any(g < 1 for g in gaps) or gaps != sorted(gaps):
    run.fail("%d login attempts in ~9 s, %s s apart: the back-off (1, 2, 4 s ...) wants 2 to 5, "
             "further and further apart" % (tries, gaps))
if box.poll() is not None:
    run.fail("a refused login stopped the box")
print("ok   a wrong password: one line (%s), %d attempts in ~9 s (%s s apart), the box goes on"
      % (re.search(r"mqtt: the broker refused[^\n]*", run.log()).group(0), tries, gaps))
stop_box(box)

# 4. The broker's certificate from an authority the box was not told: refused, said once.
box, url = start_box("otherca", tls.replace(work + "/ca.crt", work + "/other.crt"))
run.wait_for("the certificate refused", lambda: "its certificate checked against %s/other.crt"
             % work in run.log(), 20, box)
if "mqtt: connected" in run.log():
    run.fail("the box logged in to a broker whose certificate it cannot check")
print("ok   a broker certificate the CA file did not sign: refused (%s)"
      % re.search(r"mqtt: cannot reach[^\n]*", run.log()).group(0))
stop_box(box)

# 5. A password file others can read: not used, said at the error level, the box runs on.
open_file = password_file("open.pw", SECRET, 0o644)
box, url = start_box("openfile", tls.replace(good, open_file))
run.wait_for("the open password file refused", lambda: "mqtt: off: mqtt.password_file %s is "
             "readable by others (mode 0644)" % open_file in run.log(), 20, box)
if SECRET in run.log():
    run.fail("the password is in the box's log")
print("ok   a password file others can read is not used; the box runs on")
stop_box(box)

ha.loop_stop()
viewer.loop_stop()
run.stop_all()
print("mqtt login: all checks pass")
