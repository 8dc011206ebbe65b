#!/usr/bin/python3
"""A farm of 20 boxes under one broker and one Prometheus, with the files board/fleet/ ships:
promtool checks the scrape configuration and the alert rules and runs the rules' unit tests; a
real Prometheus, with the shipped configuration (its interval shortened, its discovery file this
test's), scrapes 20 sim boxes that each carry the drift history of two real sim cycles; every query
of the shipped Grafana dashboard returns each box's series; the scrapes take under 50 ms; the
broker carries every box's discovery and state, and Home Assistant sees 20 distinct devices. The
figures are printed for docs/fleet.md. Usage: fleet.py CALBOX SOURCE_DIR"""
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import urllib.parse
import urllib.request

import paho.mqtt.client as mqtt

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "network"))
from common import Run, free_port, process_mib  # noqa: E402

calbox, top = sys.argv[1], sys.argv[2]
fleet = os.path.join(top, "board", "fleet")
work = tempfile.mkdtemp(prefix="calbox-fleet-")
run = Run(work)
BOXES = 20
scenario = os.path.join(top, "tests/scenarios/delta_cycle_small.toml")


def promtool(*args, cwd=fleet):
    r = subprocess.run(["/usr/bin/promtool"] + list(args), cwd=cwd, capture_output=True, text=True)
    if r.returncode != 0:
        run.fail("promtool %s: %s%s" % (" ".join(args), r.stdout, r.stderr))
    return r.stdout


# 1. The shipped files as promtool reads them.
promtool("check", "config", "prometheus.yml")
promtool("check", "rules", "calbox_alerts.yml")
promtool("test", "rules", "calbox_alerts_test.yml")
print("ok   promtool: the scrape configuration, the alert rules and their unit tests")

# 2. A drift history from two real sim cycles, which every box then carries.
seed = os.path.join(work, "seed")
for _ in range(2):
    r = subprocess.run([calbox, "run", "--board", "sim", "--auto", "--scenario", scenario,
                        "--data", seed, "--console", ""], stdin=subprocess.DEVNULL,
                       capture_output=True, text=True)
    if r.returncode != 0:
        run.fail("a seed cycle: exit %d: %s" % (r.returncode, r.stderr[-400:]))
history = json.load(open(os.path.join(seed, "history.json")))["cycles"]
if len(history) != 2:
    run.fail("the seed history has %d cycles" % len(history))

# 3. One broker, 20 boxes beside it, each with its own node id and page.
broker, broker_port = run.broker()
seen = {}  # topic -> payload, as Home Assistant gets them
lock = threading.Lock()
ha = mqtt.Client(client_id="home-assistant")


def on_message(client, userdata, m):
    with lock:
        seen[m.topic] = m.payload.decode(errors="replace")
        counts[0] += 1


counts = [0]
ha.on_message = on_message
ha.connect("127.0.0.1", broker_port)
ha.subscribe([("homeassistant/#", 1), ("calbox/#", 1)])
ha.loop_start()

boxes = []
began = time.monotonic()
for k in range(1, BOXES + 1):
    name = "box%02d" % k
    run.work = os.path.join(work, name)
    data = os.path.join(run.work, "data")
    os.makedirs(data)
    shutil.copy(os.path.join(seed, "history.json"), data)
    box, url = run.box(calbox, top, data, ["--mqtt", "127.0.0.1:%d" % broker_port],
                       '[mqtt]\nnode_id = "%s"\n' % name)
    boxes.append((name, box, url))
started_s = time.monotonic() - began

targets = [{"targets": [url[len("http://"):]], "labels": {"box": name}}
           for name, _, url in boxes]
os.makedirs(os.path.join(work, "sd"))
json.dump(targets, open(os.path.join(work, "sd", "boxes.json"), "w"))

# 4. Prometheus with the shipped configuration: a 1 s interval, this test's discovery file.
config = open(os.path.join(fleet, "prometheus.yml")).read()
config = config.replace("scrape_interval: 30s", "scrape_interval: 1s")
config = config.replace("evaluation_interval: 30s", "evaluation_interval: 1s")
config = config.replace("/etc/prometheus/calbox/*.json", os.path.join(work, "sd", "*.json"))
config = config.replace("refresh_interval: 1m", "refresh_interval: 1s")
config = config.replace("scrape_timeout: 5s", "scrape_timeout: 1s")
if "scrape_interval: 1s" not in config or "scrape_timeout: 1s" not in config or \
        os.path.join(work, "sd") not in config:
    run.fail("the shipped prometheus.yml no longer has the lines this test adapts")
open(os.path.join(work, "prometheus.yml"), "w").write(config)
shutil.copy(os.path.join(fleet, "calbox_alerts.yml"), work)
prom_port = free_port()
prom = subprocess.Popen(["/usr/bin/prometheus", "--config.file=" + os.path.join(work, "prometheus.yml"),
                         "--storage.tsdb.path=" + os.path.join(work, "tsdb"),
                         "--web.listen-address=127.0.0.1:%d" % prom_port],
                        stdout=subprocess.DEVNULL, stderr=open(os.path.join(work, "prom.err"), "w"))
run.children.append(prom)


def query(expr):
    u = "http://127.0.0.1:%d/api/v1/query?query=%s" % (prom_port, urllib.parse.quote(expr))
    try:
        with urllib.request.urlopen(u, timeout=5) as r:
            body = json.load(r)
    except OSError:
        return None
    if body.get("status") != "success":
        run.fail("%s: %s" % (expr, body))
    return body["data"]["result"]


def all_up():
    r = query('up{job="calbox"} == 1')
    return r is not None and len(r) == BOXES
run.wait_for("Prometheus scraping all %d boxes" % BOXES, all_up, 60)
time.sleep(5)  # a few scrapes each

# 5. Every query of the dashboard returns each box's series.
names = {name for name, _, _ in boxes}
dashboard = json.load(open(os.path.join(fleet, "calbox_dashboard.json")))
exprs = [t["expr"] for p in dashboard["panels"] for t in p["targets"]]
if len(exprs) < 6:
    run.fail("the dashboard has %d queries" % len(exprs))
for expr in exprs:
    result = query(expr)
    got = {s["metric"].get("box") for s in result}
    if got != names:
        run.fail("the dashboard's %s gives boxes %s" % (expr, sorted(got - {None})[:5]))
print("ok   all %d dashboard queries return each of the %d boxes' series" % (len(exprs), BOXES))

# 6. The scrapes' time.
slowest = query('max_over_time(scrape_duration_seconds{job="calbox"}[5s])')
worst_ms = max(float(s["value"][1]) for s in slowest) * 1000
median_ms = sorted(float(s["value"][1]) for s in slowest)[len(slowest) // 2] * 1000
if worst_ms >= 50:
    run.fail("a scrape took %.1f ms (under 50 wanted)" % worst_ms)

# 7. The broker carried every box's discovery and state; Home Assistant sees 20 devices.
def discovered():
    with lock:
        devices = {json.loads(p)["device"]["identifiers"][0] for t, p in seen.items()
                   if t.endswith("/config") and p}
        states = {t for t in seen if re.fullmatch(r"calbox/box\d\d/state", t)}
    return devices if len(devices) == BOXES and len(states) == BOXES else None
devices = run.wait_for("every box's discovery and state", discovered, 30)
with lock:
    configs = sum(1 for t, p in seen.items() if t.endswith("/config") and p)
    messages = counts[0]
if configs != 5 * BOXES:  # remote start off: five configs a box, no button
    run.fail("%d discovery configs for %d boxes" % (configs, BOXES))
rss = [process_mib(box.pid, "VmRSS") for _, box, _ in boxes]
print("ok   %d boxes started in %.1f s; scrapes %.1f ms median, %.1f ms slowest; the broker carried "
      "%d messages (%d discovery configs, %d devices in Home Assistant); memory %.0f MiB a box "
      "(%.0f to %.0f)" % (BOXES, started_s, median_ms, worst_ms, messages, configs, len(devices),
                          sum(rss) / len(rss), min(rss), max(rss)))
ha.loop_stop()
run.stop_all()
print("fleet: all checks pass")
