#!/usr/bin/python3
"""Print and cut on the appliance, through the page's Place screen in a real browser (headless
Chromium, driven by Selenium) and its API: a gantry laser calibrated by the box on the sim board (examples/laser_print_and_cut.toml,
--auto), then the box started again with the printed card already on the bed. `bed-photo` with
the drawing's marks (typed on the page) finds them (marks.json), the page places the cut by
them, draws it and offers it compensated for download.
Judged here in the twin's truth, with this file's own model of the laser's gantry (the scenario's
[truth.cartesian] scales and squareness) and of the card (its turn, shift and stretches): every
point of the compensated cut, commanded at the G54 zero the marks gave, where the laser really
goes against the line the card shows. Refusals: the cut placed by marks before any were found, two marks.
Usage: web_marks.py CALBOX SOURCE_DIR"""
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from selenium.webdriver.common.by import By  # noqa: E402

from common import PASSWORD, Run, headless_chromium, password_hash, request  # noqa: E402

calbox, top = sys.argv[1], sys.argv[2]
work = tempfile.mkdtemp(prefix="calbox-marks-")
run = Run(work)
scenario = os.path.join(top, "examples/laser_print_and_cut.toml")
data = os.path.join(work, "data")

# The twin's truth as the scenario gives it, read here.
text = open(scenario).read()
def number(key):
    return float(re.search(r"^%s = ([-0-9.]+)" % key, text, re.M).group(1))
SX, SY, SQ = number("scale_error_x"), number("scale_error_y"), math.radians(number("squareness_error_deg"))
ORIGIN = (number("print_origin_x_mm"), number("print_origin_y_mm"))
TURN = math.radians(number("print_angle_deg"))
STRETCH = (number("print_stretch"), number("print_stretch_y"))
MARKS = [(0.0, 0.0), (130.0, 0.0), (130.0, 110.0), (0.0, 95.0)]
if "marks_mm = [0.0, 0.0, 130.0, 0.0, 130.0, 110.0, 0.0, 95.0]" not in text:
    run.fail("the scenario's marks are not the ones this test names")


def laser_lands(x, y):
    """Where the gantry really puts the spot for a commanded machine X Y (machine_twin.cpp's
    model: each axis's scale, the X axis leaning by the squareness error)."""
    return x * (1 + SX) + y * (1 + SY) * math.tan(SQ), y * (1 + SY)


def on_card(x, y):
    """Where a drawing's point is printed on the bed."""
    x, y = STRETCH[0] * x, STRETCH[1] * y
    return (ORIGIN[0] + math.cos(TURN) * x - math.sin(TURN) * y,
            ORIGIN[1] + math.sin(TURN) * x + math.cos(TURN) * y)


def distance_to_line(p, line):
    best = 1e300
    for (ax, ay), (bx, by) in zip(line, line[1:]):
        dx, dy = bx - ax, by - ay
        t = max(0.0, min(1.0, ((p[0] - ax) * dx + (p[1] - ay) * dy) / (dx * dx + dy * dy)))
        best = min(best, math.hypot(p[0] - ax - t * dx, p[1] - ay - t * dy))
    return best


def g1_points(job):
    return [(float(m.group(1)), float(m.group(2)))
            for m in re.finditer(r"^G1 X([-0-9.]+) Y([-0-9.]+)", job, re.M)]


# The laser calibrated by the box: the correction in force.
cycle = subprocess.run([calbox, "run", "--board", "sim", "--scenario", scenario, "--data", data,
                        "--auto"], stdin=subprocess.DEVNULL, capture_output=True, text=True)
if cycle.returncode != 0:
    run.fail("the laser's cycle: exit %d: %s" % (cycle.returncode, cycle.stderr[-400:]))
for name in ("marks.json", "stock.json"):
    if os.path.exists(os.path.join(data, name)):
        os.remove(os.path.join(data, name))
JOB = "job-cut.nc"
shutil.copy(os.path.join(top, "examples/laser_print_and_cut.gcode"), os.path.join(data, JOB))
drawing = [(float(m.group(1)), float(m.group(2))) for m in re.finditer(
    r"^G[01] X([-0-9.]+) Y([-0-9.]+)", open(os.path.join(data, JOB)).read(), re.M)]
printed = [on_card(*p) for p in drawing]

# The box started again to cut the card, which already lies on the bed.
placing = os.path.join(work, "placing.toml")
with open(placing, "w") as f:
    f.write(text.replace('job = "laser_print_and_cut.gcode"',
                         'job = "%s/examples/laser_print_and_cut.gcode"' % top)
            .replace("[placement]\n", "[placement]\non_bed_at_start = true\n"))
box, url = run.box(calbox, top, data, [], '[web]\npassword = "%s"\n' % password_hash(PASSWORD),
                   scenario=placing)
try:
    # Placed by marks before any were found: refused, naming what to do.
    status, _, body = request(url + "/api/action", "POST",
                              {"action": "compensate", "job": JOB, "work_zero": "marks"},
                              password=PASSWORD)
    if status != 409 or b"no printed marks found on the bed: take a bed photo with the marks" not in body:
        run.fail("compensate by marks with none found: %d %r" % (status, body[:200]))
    status, _, body = request(url + "/api/action", "POST",
                              {"action": "bed-photo", "marks": "0,0 130,0"}, password=PASSWORD)
    if status != 409 or b"marks: three or four X,Y, 2 given" not in body:
        run.fail("a bed photo with two marks: %d %r" % (status, body[:200]))

    # The owner's way, in a real browser: the Place screen, the card's top and its marks typed,
    # the bed photographed; the job then goes by the marks, drawn on the bed, compensated and
    # offered for download.
    driver = headless_chromium(work, 1400)
    try:
        driver.get(url + "/")
        run.wait_for("the page showing idle",
                     lambda: driver.find_element(By.ID, "state").text == "idle", 15, box)
        driver.find_element(By.CSS_SELECTOR, "button[data-view='place']").click()
        driver.find_element(By.ID, "password").send_keys(PASSWORD)
        driver.find_element(By.ID, "bed-surface").send_keys("0.3")
        driver.find_element(By.ID, "bed-marks").send_keys(" ".join("%g,%g" % m for m in MARKS))
        driver.find_element(By.ID, "btn-bed-photo").click()
        said = run.wait_for("the bed photo's reply on the page", lambda: re.search(
            r"^bed photo: .*the surface 0.300 mm above it \(as given\); .*the drawing's marks found \(marks.json\): "
            r"4 marks, its zero at machine X([-0-9.]+) Y([-0-9.]+) mm, turned ([-0-9.]+) deg",
            driver.find_element(By.ID, "bed-reply").text), 120, box)
        zero = (float(said.group(1)), float(said.group(2)))
        if driver.find_element(By.ID, "place-zero").get_attribute("value") != "marks":
            run.fail("the work zero after the marks were found is %r, not marks"
                     % driver.find_element(By.ID, "place-zero").get_attribute("value"))
        points = run.wait_for("the cut drawn on the bed view", lambda: driver.execute_script(
            "const p = document.getElementById('bed-job-path');"
            "return p ? p.getAttribute('points') : null;"), 30, box)
        if len(points.split()) < len(drawing) - 1:
            run.fail("the cut drawn with %d points, the job has %d" % (len(points.split()), len(drawing)))
        frame = driver.find_element(By.ID, "place-frame").text
        if "job placed with the printed marks: marks.json's 4 marks" not in frame:
            run.fail("the page's frame line does not say the marks place the job: %r" % frame)
        driver.find_element(By.ID, "btn-place").click()
        link = run.wait_for("the compensated cut's download link", lambda: driver.execute_script(
            "const a = document.getElementById('place-download-link'); return a ? a.href : null;"),
            60, box)
    finally:
        driver.quit()
    marks_file = os.path.join(data, "marks.json")
    found = json.load(open(marks_file))
    if found.get("schema") != "calbox.registration/1" or len(found["marks"]) != 4:
        run.fail("marks.json: %s" % json.dumps(found)[:300])
    worst_mark = max(m["residual_mm"] for m in found["marks"])
    print("marks: %d found, worst residual %.4f mm" % (len(found["marks"]), worst_mark))
    if worst_mark > 0.05:
        run.fail("a mark the box found is %.4f mm from where its fit puts it" % worst_mark)
    status, headers, body = request(link)
    if status != 200 or 'filename="job-cut-compensated.nc"' not in headers.get("Content-Disposition", ""):
        run.fail("the download: %d %s" % (status, headers.get("Content-Disposition")))
    job = body.decode()
    # G54 at the drawing's zero the marks gave: each written point, commanded there, lands on the
    # printed line.
    points = g1_points(job)
    offs = [distance_to_line(laser_lands(zero[0] + x, zero[1] + y), printed) for x, y in points]
    mean, worst = sum(offs) / len(offs), max(offs)
    print("the cut placed by the page's marks: %d points, %.4f mm mean, %.4f mm worst from the "
          "printed line" % (len(points), mean, worst))
    if len(points) < len(drawing) - 1 or worst > 0.1 or mean > 0.05:
        run.fail("the cut placed by marks: %d points, %.4f mean, %.4f worst" % (len(points), mean, worst))
finally:
    run.stop_all()
print("web marks complete")
