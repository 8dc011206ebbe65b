#!/usr/bin/python3
"""The box's web page in a real browser and its MQTT in Home Assistant's place, through one cycle
on the sim board: headless Chromium (driven by Selenium), trusting a test authority, opens the
page over https (sent there from the plain port), sees the live view change,
presses Start, confirms at review and reads the result, keeping screenshots of the status, set-up
and result views; paho-mqtt stands for Home Assistant on a Mosquitto broker: the discovery configs
arrive retained and well-formed (and again when Home Assistant says it is back), the state goes
through the cycle, its button starts one, and the box's availability goes offline when it is
killed. /metrics is parsed by Prometheus' own parser and its figures are the cycle's.
Usage: web_browser.py CALBOX SOURCE_DIR SCREENSHOT_DIR [--tls]"""
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time

import paho.mqtt.client as mqtt
from prometheus_client.parser import text_string_to_metric_families
from selenium.common.exceptions import NoSuchElementException
from selenium.webdriver.common.by import By

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import PASSWORD, Run, headless_chromium, get_json, password_hash, request, sh_in  # noqa: E402

calbox, top, shots = sys.argv[1], sys.argv[2], sys.argv[3]
os.makedirs(shots, exist_ok=True)
work = tempfile.mkdtemp(prefix="calbox-web-")
run = Run(work)
NODE = "bench1"

# Home Assistant's side: every message kept with its retain flag.
messages = []
lock = threading.Lock()


def on_message(client, userdata, m):
    with lock:
        messages.append((m.topic, m.payload.decode(errors="replace"), bool(m.retain)))


def seen(predicate):
    with lock:
        return [m for m in messages if predicate(m)]


broker, broker_port = run.broker()
ha = mqtt.Client(client_id="home-assistant")
ha.on_message = on_message
ha.connect("127.0.0.1", broker_port)
ha.subscribe([("homeassistant/#", 1), ("calbox/#", 1)])
ha.loop_start()

# Home Assistant's button starts a cycle here: remote start on (it is off by default).
config = '[web]\npassword = "%s"\n\n[mqtt]\nnode_id = "%s"\nremote_start = true\n' % (password_hash(PASSWORD), NODE)
box, url = run.box(calbox, top, os.path.join(work, "data"),
                   ["--mqtt", "127.0.0.1:%d" % broker_port, "--operator"], config)

# Discovery: six configs, retained, each well-formed and pointing at this box's topics.
EXPECTED = {"sensor/%s/last_error" % NODE, "sensor/%s/drift" % NODE,
            "sensor/%s/last_calibrated" % NODE, "sensor/%s/state" % NODE,
            "binary_sensor/%s/needs_calibrating" % NODE, "button/%s/start" % NODE}


def discovery():
    found = {}
    for topic, payload, retained in seen(lambda m: m[0].endswith("/config")):
        found[topic[len("homeassistant/"):-len("/config")]] = (payload, retained)
    return found if set(found) >= EXPECTED else None


configs = run.wait_for("Home Assistant's discovery configs", discovery, 15, box)
# Retained: a client that subscribes afterwards (Home Assistant starting later) gets them all.
late_messages = []
late = mqtt.Client(client_id="home-assistant-later")
late.on_message = lambda c, u, m: late_messages.append((m.topic, bool(m.retain)))
late.connect("127.0.0.1", broker_port)
late.subscribe([("homeassistant/#", 1), ("calbox/%s/availability" % NODE, 1)])
late.loop_start()
run.wait_for("the discovery configs retained", lambda: {
    t[len("homeassistant/"):-len("/config")] for t, r in late_messages if r} >= EXPECTED, 10, box)
run.wait_for("availability retained", lambda: ("calbox/%s/availability" % NODE, True) in late_messages,
             10, box)
late.loop_stop()
for key, (payload, retained) in configs.items():
    c = json.loads(payload)
    if c["availability_topic"] != "calbox/%s/availability" % NODE:
        run.fail("discovery %s: availability topic %s" % (key, c["availability_topic"]))
    if not c["unique_id"].startswith("calbox_%s_" % NODE) or c["device"]["identifiers"] != ["calbox_" + NODE]:
        run.fail("discovery %s: ids %s %s" % (key, c["unique_id"], c["device"]))
    if key.startswith("button/"):
        if c["command_topic"] != "calbox/%s/command" % NODE or c["payload_press"] != "start":
            run.fail("the start button's config: %s" % payload)
    elif c["state_topic"] != "calbox/%s/state" % NODE or "value_json." not in c["value_template"]:
        run.fail("discovery %s: %s" % (key, payload))
build = subprocess.run([calbox, "--version"], capture_output=True, text=True).stdout.split()[-1]
if any(json.loads(payload)["device"].get("sw_version") != build for payload, _ in configs.values()):
    run.fail("discovery: the device's sw_version is not the build's " + build)
if json.loads(configs["sensor/%s/last_error" % NODE][0])["unit_of_measurement"] != "mm":
    run.fail("the last error's unit is not mm")
run.wait_for("availability online", lambda: seen(
    lambda m: m[0] == "calbox/%s/availability" % NODE and m[1] == "online"), 10, box)
# Home Assistant restarting says so on its status topic: the configs come again.
count = len(seen(lambda m: m[0].endswith("/config")))
ha.publish("homeassistant/status", "online")
run.wait_for("discovery again after homeassistant/status online",
             lambda: len(seen(lambda m: m[0].endswith("/config"))) >= count + len(EXPECTED), 10, box)

# The page is over https (the test runs with --tls), its certificate from the test authority,
# which the browser trusts as a person's would: in NSS's database under its home. The box's
# fingerprint is the one openssl reads from the certificate file.
ca_file = os.path.join(work, "ca.crt")
page_cert = os.path.join(work, "page.crt")
fingerprint = subprocess.run(["openssl", "x509", "-noout", "-fingerprint", "-sha256", "-in",
                              page_cert], check=True, capture_output=True,
                             text=True).stdout.strip().split("=", 1)[1]
if "SHA-256 " + fingerprint not in run.log():
    run.fail("the box's log does not give the certificate's fingerprint %s" % fingerprint)
home = os.path.join(work, "home")
nssdb = "sql:" + os.path.join(home, ".pki", "nssdb")
os.makedirs(os.path.join(home, ".pki", "nssdb"))
sh_in(work, "certutil", "-d", nssdb, "-N", "--empty-password")
sh_in(work, "certutil", "-d", nssdb, "-A", "-t", "C,,", "-n", "calbox test CA", "-i", ca_file)
os.environ["HOME"] = home

# The browser.
driver = headless_chromium(work, 1000)


def text(element_id):
    return driver.find_element(By.ID, element_id).text


def cell(row_id):
    # The result's rows are built when the page has fetched the result: until then there is none.
    try:
        return driver.find_element(By.CSS_SELECTOR, "#%s td" % row_id).text
    except NoSuchElementException:
        return ""


def tab(view):
    driver.find_element(By.CSS_SELECTOR, "button[data-view='%s']" % view).click()


try:
    # Asked on the plain port, the browser is sent on to https, and trusts what it finds there.
    driver.get("http://127.0.0.1:%d/" % run.plain_port)
    if driver.title != "calbox" or driver.current_url != url + "/":
        run.fail("the page's title is %r at %s" % (driver.title, driver.current_url))
    run.wait_for("the page showing idle", lambda: text("state") == "idle", 15, box)
    run.wait_for("the page's websocket", lambda: text("link") == "live", 10, box)

    # The live view: frames keep coming, and what they show changes.
    tab("setup")
    LIVE = ("const img = document.getElementById('live');"
            "if (!img.complete || !img.naturalWidth) return null;"
            "const c = document.createElement('canvas'); c.width = img.naturalWidth;"
            "c.height = img.naturalHeight; const x = c.getContext('2d'); x.drawImage(img, 0, 0);"
            "const d = x.getImageData(0, 0, c.width, c.height).data; let s = 0;"
            "for (let i = 0; i < d.length; i += 4) s += d[i];"
            "return [Number(document.getElementById('frame').textContent), s, c.width];")
    views = []

    def next_view():
        v = driver.execute_script(LIVE)
        if v and v[0] > 0 and (not views or v[0] > views[-1][0]):
            views.append(v)
        return len(views) >= 3
    run.wait_for("three live frames", next_view, 60, box)
    if len({v[1] for v in views}) < 2:
        run.fail("the live view did not change over frames %s" % [v[0] for v in views])
    if views[-1][2] != 960:
        run.fail("the live view is %d px wide, not 960" % views[-1][2])
    if not re.fullmatch(r"\d+", text("sharpness")):
        run.fail("no sharpness figure: %r" % text("sharpness"))
    driver.save_screenshot(os.path.join(shots, "web-setup.png"))

    # Start, with the password typed as a person would.
    tab("status")
    driver.find_element(By.ID, "password").send_keys(PASSWORD)
    driver.find_element(By.ID, "btn-start").click()
    run.wait_for("the cycle to leave idle", lambda: text("state") != "idle", 15, box)
    run.wait_for("the review on the page", lambda: "apply" in text("waiting"), 120, box)
    driver.save_screenshot(os.path.join(shots, "web-status.png"))
    driver.find_element(By.ID, "btn-confirm").click()
    run.wait_for("the cycle completed on the page",
                 lambda: text("state") == "idle" and text("completed") == "1", 120, box)
    tab("result")
    run.wait_for("the result's figures", lambda: cell("result-after-rms") not in ("", "–"), 15, box)
    pictures = run.wait_for("the cycle's pictures", lambda: driver.execute_script(
        "const i = [...document.querySelectorAll('#pictures img')];"
        "return i.length > 0 && i.every((x) => x.complete && x.naturalWidth > 0) ? i.length : 0;"), 30, box)
    names = driver.execute_script("return [...document.querySelectorAll('#pictures img')].map((i) => i.alt);")
    for wanted in ("cycle-0001-overlay.png", "cycle-0001-error-field.png", "cycle-0001-screen-01.png"):
        if wanted not in names:
            run.fail("the result view lacks %s: %s" % (wanted, names))
    driver.save_screenshot(os.path.join(shots, "web-result.png"))
    page_after_rms = float(cell("result-after-rms").split()[0])
    page_before_rms = float(cell("result-before-rms").split()[0])
    if cell("result-result") != "applied":
        run.fail("the page's result is %r" % cell("result-result"))
    # With the set-up done, the live view draws the bed's expected outline.
    tab("setup")
    first = views[-1][0]
    run.wait_for("a live frame after the cycle", lambda: next_view() and views[-1][0] > first + 1, 30, box)
    driver.save_screenshot(os.path.join(shots, "web-setup-guide.png"))
finally:
    driver.quit()

# The page's figures are the cycle's: its last verification as the log states it.
verified = re.findall(r"verified on the re-printed target: XY ([0-9.]+) mm RMS, ([0-9.]+) mm worst",
                      run.log())
if not verified:
    run.fail("no verification line in the log")
if abs(page_after_rms - float(verified[-1][0])) > 0.00005:
    run.fail("the page's after RMS %.4f is not the cycle's %s" % (page_after_rms, verified[-1][0]))
if not page_after_rms < page_before_rms / 10:
    run.fail("after %.4f is not a tenth of before %.4f" % (page_after_rms, page_before_rms))

# /metrics, parsed by Prometheus' own parser.
status, headers, body = request(url + "/metrics")
if status != 200 or not headers["Content-Type"].startswith("text/plain; version=0.0.4"):
    run.fail("/metrics: %d %s" % (status, headers["Content-Type"]))
samples = {}
for family in text_string_to_metric_families(body.decode()):
    for s in family.samples:
        samples[(s.name, tuple(sorted(s.labels.items())))] = s.value
if samples.get(("calbox_cycles_total", (("mode", "delta"), ("result", "applied")))) != 1:
    run.fail("calbox_cycles_total: %s" % [k for k in samples if k[0] == "calbox_cycles_total"])
after_m = samples[("calbox_last_error_metres", (("figure", "rms"), ("stage", "after")))]
worst_m = samples[("calbox_last_error_metres", (("figure", "max"), ("stage", "after")))]
if abs(after_m * 1000 - float(verified[-1][0])) > 0.00005 or abs(worst_m * 1000 - float(verified[-1][1])) > 0.00005:
    run.fail("metrics after %.6g m, %.6g m are not the cycle's %s" % (after_m, worst_m, verified[-1]))
if samples[("calbox_state", (("state", "idle"),))] != 1:
    run.fail("calbox_state idle is not 1")
history = get_json(url + "/api/history")["cycles"]
if abs(samples[("calbox_last_calibration_timestamp_seconds", ())] - history[-1]["finished_unix_s"]) > 0:
    run.fail("the last calibration's time is not the history's")
if abs(time.time() - history[-1]["finished_unix_s"]) > 300:
    run.fail("the history's time is not now")
for part in ("box", "camera", "machine"):
    if not samples[("calbox_last_cycle_duration_seconds", (("part", part),))] > 0:
        run.fail("no %s duration" % part)
version = subprocess.run([calbox, "--version"], capture_output=True, text=True).stdout.split()[-1]
if ("calbox_build_info", (("version", version),)) not in samples:
    run.fail("no build info of version " + version)

# MQTT through the cycle: the states in order, the result with its figures.
states = [json.loads(p)["state"] for t, p, _ in seen(lambda m: m[0] == "calbox/%s/state" % NODE)]
order = ["idle", "setup-camera", "setup-plane", "make-target", "review", "apply", "verify", "idle"]
at = 0
for s in states:
    if at < len(order) and s == order[at]:
        at += 1
if at != len(order):
    run.fail("the MQTT states %s do not go through %s" % (states, order))
result = json.loads(seen(lambda m: m[0] == "calbox/%s/result" % NODE)[-1][1])
if result["result"] != "applied" or abs(result["after"]["rms_mm"] - float(verified[-1][0])) > 0.00005:
    run.fail("the MQTT result: %s" % result)
last_state = json.loads(states and seen(lambda m: m[0] == "calbox/%s/state" % NODE)[-1][1])
if last_state["needs_calibration"] is not True or last_state["last_error_mm"] != result["before"]["rms_mm"]:
    run.fail("the state after the cycle: %s (before %s, limit 0.05 mm)" % (last_state, result["before"]))

# Home Assistant's button starts a cycle; the page's cancel ends it.
ha.publish("calbox/%s/command" % NODE, "start")
run.wait_for("the button's cycle", lambda: get_json(url + "/api/status")["state"] != "idle", 15, box)
status, _, body = request(url + "/api/action", "POST", {"action": "cancel"}, password=PASSWORD)
if status != 200:
    run.fail("cancel: %d %s" % (status, body))
run.wait_for("idle after the cancel", lambda: get_json(url + "/api/status")["state"] == "idle", 30, box)

# Killed, the box cannot say goodbye: its last will says it for it.
box.send_signal(signal.SIGKILL)
box.wait()
run.wait_for("availability offline (the last will)", lambda: seen(
    lambda m: m[0] == "calbox/%s/availability" % NODE and m[1] == "offline"), 15)
ha.loop_stop()
run.stop_all()
print("web page and MQTT: live view %d frames, %d pictures, after %.4f mm (before %.4f), "
      "%d MQTT states, discovery %d configs" % (len(views), pictures, page_after_rms,
                                                  page_before_rms, len(states), len(configs)))
