#!/usr/bin/python3
"""The page's Place screen in a real browser (headless Chromium, driven by Selenium), on a box
that has calibrated a router on the sim board: the bed view shown, a job from the data directory
drawn over it, the owner's click on the bed turned into the job's work zero, the job compensated
and offered for download. Judged by the bed view's world file (read here, not by the page), by
where the drawn job's corners lie on it, and by the command line's own compensation of the same
job at the same zero.
Usage: web_place.py CALBOX SOURCE_DIR SCREENSHOT_DIR"""
import json
import math
import os
import re
import subprocess
import sys
import tempfile

from selenium.common.exceptions import NoAlertPresentException
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import PASSWORD, Run, headless_chromium, get_json, password_hash, request  # noqa: E402

calbox, top, shots = sys.argv[1], sys.argv[2], sys.argv[3]
os.makedirs(shots, exist_ok=True)
work = tempfile.mkdtemp(prefix="calbox-place-")
run = Run(work)
scenario = "tests/scenarios/router_stock_small.toml"
data = os.path.join(work, "data")

# A router calibrated by the box: the correction in force and the cycle's bed view.
cycle = subprocess.run([calbox, "run", "--board", "sim", "--scenario", os.path.join(top, scenario),
                        "--data", data, "--auto"], stdin=subprocess.DEVNULL,
                       capture_output=True, text=True)
if cycle.returncode != 0:
    run.fail("the planar cycle: exit %d: %s" % (cycle.returncode, cycle.stderr[-400:]))
# A 40 x 30 mm pocket outline around G54's zero, as CAM writes one.
JOB = "job-pocket.nc"
CORNERS = [(0, 0), (40, 0), (40, 30), (0, 30)]
with open(os.path.join(data, JOB), "w") as f:
    f.write("G21 G90 G54\nG0 Z5\nG0 X0 Y0\nM3 S12000\nG1 Z-1 F300\nG1 X40 Y0 F600\nG1 X40 Y30\n"
            "G1 X0 Y30\nG1 X0 Y0\nG0 Z5\nM5\nM2\n")

# The box started again to place a job, the scenario's sheet already lying on the bed.
SHEET_MM = 2.35  # the twin's truth, for the judge of the probed top below
placing = os.path.join(work, "placing.toml")
with open(placing, "w") as f:
    f.write(open(os.path.join(top, scenario)).read()
            .replace('job = "../../examples/', 'job = "%s/examples/' % top)
            .replace("[placement]\n", "[placement]\non_bed_at_start = true\n")
            # A sheet thicker than the machine file's surface, and a touch probe to measure it
            # (G54's Z zero, the bed's top, at machine Z -62.5).
            .replace("thickness_mm = 1.5\n", "thickness_mm = %.2f\n" % SHEET_MM)
            .replace("g54_y_mm = -300.0\n", "g54_y_mm = -300.0\ng54_z_mm = -62.5\n")
            + "\n[touch_probe]\nclear_z_mm = -40.0\n")
box, url = run.box(calbox, top, data, [], '[web]\npassword = "%s"\n' % password_hash(PASSWORD),
                   scenario=placing)

driver = headless_chromium(work, 1400)


def _alert(browser):
    try:
        return browser.switch_to.alert
    except NoAlertPresentException:
        return None


def pixel_of(x, y):
    return (x - c) / a + 0.5, (y - f) / e + 0.5


try:
    driver.get(url + "/")
    run.wait_for("the page showing idle", lambda: driver.find_element(By.ID, "state").text == "idle",
                 15, box)
    driver.find_element(By.CSS_SELECTOR, "button[data-view='place']").click()
    size = run.wait_for("the bed view on the Place screen", lambda: driver.execute_script(
        "const i = document.getElementById('bed');"
        "return i.complete && i.naturalWidth > 0 && typeof bed === 'object' && bed ?"
        " [i.naturalWidth, i.naturalHeight] : null;"), 20, box)
    if "cycle-0001-bed-view.png" not in driver.find_element(By.ID, "bed-caption").text:
        run.fail("the caption names another view: %r" % driver.find_element(By.ID, "bed-caption").text)
    # The bed as it is now: a fresh photo through the same camera, plane and correction, shown
    # in place of the cycle's.
    driver.find_element(By.ID, "password").send_keys(PASSWORD)
    driver.find_element(By.ID, "btn-bed-photo").click()
    run.wait_for("the fresh bed view on the page", lambda: driver.find_element(
        By.ID, "bed-caption").text.startswith("bed-view.png: "), 60, box)
    said = driver.find_element(By.ID, "bed-reply").text
    if not said.startswith("bed photo: bed-view.png and bed-view.pgw: the bed now, the surface 1.500 mm "
                           "above it (the machine file's); the sheet found (stock.json): its front-left corner at machine X"):
        run.fail("the page's bed photo reply: %r" % said)
    world = open(os.path.join(data, "bed-view.pgw")).read()
    if world != open(os.path.join(data, "cycle-0001-bed-view.pgw")).read():
        run.fail("the fresh view's world file %r is not the cycle's (the same travel and scale)" % world)
    # The world file, read here: machine X = c + a col, Y = f + e row at pixel centres.
    a, _, _, e, c, f = (float(v) for v in world.split())
    size = run.wait_for("the fresh bed view loaded", lambda: driver.execute_script(
        "const i = document.getElementById('bed');"
        "return i.complete && i.naturalWidth > 0 && bed && bed.name === 'bed-view.png' ?"
        " [i.naturalWidth, i.naturalHeight] : null;"), 20, box)
    # The sheet found: the job goes to its corner nearest the machine's zero (grbl's back right),
    # turned with the sheet, drawn there before anything runs.
    if driver.find_element(By.ID, "place-zero").get_attribute("value") != "camera":
        run.fail("the work zero after a sheet was found is %r, not camera"
                 % driver.find_element(By.ID, "place-zero").get_attribute("value"))
    sheet = json.load(open(os.path.join(data, "stock.json")))
    nearest = min(sheet["corners"], key=lambda c: math.hypot(*c["machine_mm"]))
    turn = math.radians(sheet["rotation_deg"])
    points = run.wait_for("the job drawn at the sheet's corner", lambda: driver.execute_script(
        "const p = document.getElementById('bed-job-path');"
        "return p ? p.getAttribute('points') : null;"), 20, box)
    drawn = [tuple(float(v) for v in p.split(",")) for p in points.split()]
    zx, zy = nearest["machine_mm"]
    for corner in CORNERS:
        x, y = pixel_of(zx + corner[0] * math.cos(turn) - corner[1] * math.sin(turn),
                        zy + corner[0] * math.sin(turn) + corner[1] * math.cos(turn))
        if not any(abs(px - x) < 0.01 and abs(py - y) < 0.01 for px, py in drawn):
            run.fail("the pocket's corner %s at the sheet's %s corner is not drawn at view pixel "
                     "(%.2f, %.2f): %s" % (corner, nearest["name"], x, y, drawn))
    frame = driver.find_element(By.ID, "place-frame").text
    if "the camera: stock.json's %s corner at machine X%.3f Y%.3f mm" % (nearest["name"], zx, zy) not in frame:
        run.fail("the frame line does not name the sheet's %s corner: %r" % (nearest["name"], frame))
    driver.save_screenshot(os.path.join(shots, "web-place-sheet.png"))
    jobs = [o.text for o in Select(driver.find_element(By.ID, "place-job")).options]
    if jobs != [JOB]:
        run.fail("the jobs offered are %s, not [%s]" % (jobs, JOB))

    # The owner clicks where the pocket's zero goes: machine X-250 Y-200, as the world file
    # puts it on the picture.
    want = (-250.0, -200.0)
    img = driver.find_element(By.ID, "bed")
    rect = driver.execute_script("const r = arguments[0].getBoundingClientRect();"
                                 "return [r.left, r.top, r.width, r.height];", img)
    scale = rect[2] / size[0]  # CSS pixels a view pixel
    col, row = pixel_of(*want)
    dx, dy = round(col * scale - rect[2] / 2), round(row * scale - rect[3] / 2)
    ActionChains(driver).move_to_element_with_offset(img, dx, dy).click().perform()
    # Where that CSS pixel is on the bed (the world file's mapping, worked here).
    clicked = (c + a * ((rect[2] / 2 + dx) / scale - 0.5), f + e * ((rect[3] / 2 + dy) / scale - 0.5))
    zero_text = run.wait_for("the work zero from the click", lambda: (lambda v: v if v != "camera" else None)(
        driver.find_element(By.ID, "place-zero").get_attribute("value")), 10, box)
    zero = tuple(float(v) for v in zero_text.split(","))
    # Selenium may click the CSS pixel's centre or its corner: half a CSS pixel on the bed.
    slack = abs(a) / scale
    if max(abs(zero[0] - clicked[0]), abs(zero[1] - clicked[1])) > slack or \
            max(abs(zero[0] - want[0]), abs(zero[1] - want[1])) > 2 * slack:
        run.fail("the click at %s (aimed at %s) gave the work zero %s" % (clicked, want, zero_text))

    # The job drawn before anything runs: its corners where zero + corner lies on the view (the
    # drawing the sheet's corner gave is replaced when the page has the clicked zero's).
    def drawn_at_zero():
        points = driver.execute_script("const p = document.getElementById('bed-job-path');"
                                       "return p ? p.getAttribute('points') : null;")
        drawn = [tuple(float(v) for v in p.split(",")) for p in (points or "").split()]
        return all(any(abs(px - x) < 0.01 and abs(py - y) < 0.01 for px, py in drawn)
                   for x, y in (pixel_of(zero[0] + cx, zero[1] + cy) for cx, cy in CORNERS))
    run.wait_for("the pocket's corners drawn at view pixels of the clicked zero + corner",
                 drawn_at_zero, 20, box)
    frame = driver.find_element(By.ID, "place-frame").text
    if "G54 zero at machine X%.3f Y%.3f mm" % zero not in frame:
        run.fail("the page's frame line does not give the clicked zero %s: %r" % (zero_text, frame))
    driver.save_screenshot(os.path.join(shots, "web-place.png"))

    # Compensated through the correction in force, then offered for download.
    driver.find_element(By.ID, "btn-place").click()
    link = run.wait_for("the compensated job's download link", lambda: driver.execute_script(
        "const a = document.getElementById('place-download-link'); return a ? a.href : null;"), 60, box)
    reply = driver.find_element(By.ID, "place-reply").text
    if not reply.startswith("compensate: job-pocket-compensated.nc: ") or "moves corrected" not in reply:
        run.fail("the page's reply: %r" % reply)
    driver.save_screenshot(os.path.join(shots, "web-place-compensated.png"))

    # The controller's G54 set there, after the owner has read what will be sent and said yes;
    # the twin's grbl reports it back ($#).
    driver.find_element(By.ID, "btn-zero").click()
    alert = run.wait_for("the confirmation", lambda: _alert(driver), 10, box)
    command = "G10 L2 P1 X%.3f Y%.3f" % zero
    if command not in alert.text:
        run.fail("the confirmation does not say what will be sent (%s): %r" % (command, alert.text))
    alert.accept()
    run.wait_for("the zero read back", lambda: driver.find_element(By.ID, "place-reply").text.startswith(
        "work zero: the controller's G54 zero at machine X%.3f Y%.3f (sent '%s', read back by $#)"
        % (zero[0], zero[1], command)), 30, box)
except BaseException:
    # A browser's exception leaves no box behind.
    run.stop_all()
    raise
finally:
    driver.quit()

# A zero beyond the travel is refused before anything is sent; without confirm nothing is sent.
status, _, refused = request(url + "/api/action", "POST", {"action": "work-zero", "work_zero": "10,10",
                                                            "confirm": True}, password=PASSWORD)
if status != 409 or b"work zero: machine X10.000 Y10.000 is beyond the machine file's travel" not in refused:
    run.fail("a zero beyond the travel: %d %s" % (status, refused[:200]))
status, _, answer = request(url + "/api/action", "POST", {"action": "work-zero", "work_zero": "camera"},
                            password=PASSWORD)
if status != 200 or json.loads(answer)["sent"] is not False:
    run.fail("work zero without confirm: %d %s" % (status, answer[:200]))
# A height the console would refuse is refused through the page too, naming the figure.
status, _, refused = request(url + "/api/action", "POST", {"action": "bed-photo", "surface_mm": -2},
                             password=PASSWORD)
if status != 409 or b"'-2.000' is not a height in millimetres" not in refused:
    run.fail("a bed photo at -2 mm: %d %s" % (status, refused[:200]))
status, headers, body = request(link)
if status != 200 or 'filename="job-pocket-compensated.nc"' not in headers.get("Content-Disposition", ""):
    run.fail("the download: %d %s" % (status, headers.get("Content-Disposition")))
# The same job at the same zero through the command line: the same moves (the mark's date aside).
reference = os.path.join(work, "reference.nc")
subprocess.run([calbox, "compensate", "--result", os.path.join(data, "planar-result.json"),
                os.path.join(data, JOB), "--work-zero", zero_text, "-o", reference],
               check=True, capture_output=True, stdin=subprocess.DEVNULL)
page_lines = body.decode().splitlines()
cli_lines = open(reference).read().splitlines()
if page_lines[1:] != cli_lines[1:] or len(page_lines) < 12:
    run.fail("the page's job differs from the command line's at the same zero:\n%s\n---\n%s"
             % ("\n".join(page_lines[:8]), "\n".join(cli_lines[:8])))
# The desk places by the sheet too (the console's `compensate JOB camera CORNER`, sent here as
# the page sends it): the same job as the command line's at that corner of stock.json.
status, _, answer = request(url + "/api/action", "POST", {"action": "compensate", "job": JOB,
                                                           "work_zero": "camera front-left"},
                            password=PASSWORD)
if status != 200:
    run.fail("compensate at the sheet's front-left corner: %d %s" % (status, answer[:200]))
run.wait_for("the desk's line for the sheet's corner", lambda: any(
    "stock.json's front-left corner" in line and line.startswith("compensate: job-pocket-compensated.nc: ")
    for line in get_json(url + "/api/status")["log"]), 30, box)
_, _, body = request(url + "/records/job-pocket-compensated.nc")
subprocess.run([calbox, "compensate", "--result", os.path.join(data, "planar-result.json"),
                os.path.join(data, JOB), "--work-zero", "camera", "--stock", os.path.join(data, "stock.json"),
                "--corner", "front-left", "-o", reference],
               check=True, capture_output=True, stdin=subprocess.DEVNULL)
if body.decode().splitlines()[1:] != open(reference).read().splitlines()[1:]:
    run.fail("the desk's job at the sheet's corner differs from the command line's")
# The stock's top by the router's touch probe (grbl's G38.2 on the twin's router, the sheet on
# its bed): the points at stock.json's corner shown first, nothing sent; then sent; the height
# judged against the twin's truth, then taken by the next bed photo.
status, _, answer = request(url + "/api/action", "POST", {"action": "probe-stock"}, password=PASSWORD)
shown = json.loads(answer) if status == 200 else {}
if (status != 200 or shown.get("sent") is not False or "G38.2 Z-25.000 F60.0" not in shown["commands"]
        or "stock.json's back-right corner" not in shown["from"]):
    run.fail("probe stock without confirm: %d %s" % (status, answer[:300]))
status, _, answer = request(url + "/api/action", "POST", {"action": "probe-stock", "confirm": True},
                            password=PASSWORD)
if status != 200 or json.loads(answer)["sent"] is not True:
    run.fail("probe stock: %d %s" % (status, answer[:300]))
probed = run.wait_for("the probe's line", lambda: next((
    line for line in get_json(url + "/api/status")["log"] if line.startswith("probe stock: ")), None), 30, box)
found = re.match(r"probe stock: the sheet's top ([0-9.]+) mm above the bed \(\+/-0.014; touched at "
                 r"machine Z(-[0-9.]+) on the sheet, Z(-[0-9.]+) beside it\), kept as stock-top.json", probed)
if not found or abs(float(found.group(1)) - SHEET_MM) > 0.03 or abs(float(found.group(3)) + 62.5) > 0.4:
    run.fail("the probed top against the sheet's %.2f mm: %s" % (SHEET_MM, probed))
top_mm = float(found.group(1))
status, _, answer = request(url + "/api/action", "POST", {"action": "bed-photo"}, password=PASSWORD)
if status != 200:
    run.fail("a bed photo after the probe: %d %s" % (status, answer[:200]))
photo_line = run.wait_for("the bed photo at the probed top", lambda: next((
    line for line in reversed(get_json(url + "/api/status")["log"])
    if line.startswith("bed photo: ") and "(probed, stock-top.json)" in line), None), 60, box)
if ("the surface %.3f mm above it (probed, stock-top.json)" % top_mm not in photo_line or
        abs(json.load(open(os.path.join(data, "stock.json")))["surface_height_mm"] - top_mm) > 1e-9):
    run.fail("the bed photo after the probe: %s" % photo_line)
# Refused before anything moves: a point beyond the travel; the points the wrong way round (the
# bed's first) are probed and refused by their heights, the kept height removed with them.
status, _, refused = request(url + "/api/action", "POST", {"action": "probe-stock", "on": "10,10",
                                                            "beside": "-290,-290", "confirm": True},
                             password=PASSWORD)
if status != 409 or b"probe stock: machine X10.000 Y10.000 is beyond the machine file's travel" not in refused:
    run.fail("a probe point beyond the travel: %d %s" % (status, refused[:200]))
on, beside = shown["commands"][3].split()[2:], shown["commands"][8].split()[2:]
swapped = {"action": "probe-stock", "on": ",".join(w[1:] for w in beside),
           "beside": ",".join(w[1:] for w in on), "confirm": True}
status, _, answer = request(url + "/api/action", "POST", swapped, password=PASSWORD)
if status != 200:
    run.fail("probe stock at swapped points: %d %s" % (status, answer[:200]))
wrong = run.wait_for("the refusal of a sheet below the bed", lambda: next((
    line for line in get_json(url + "/api/status")["log"]
    if line.startswith("probe stock: the sheet touched at machine Z")), None), 30, box)
if "is no sheet's" not in wrong or "no height kept" not in wrong or os.path.exists(
        os.path.join(data, "stock-top.json")):
    run.fail("the swapped points: %s" % wrong)
run.stop_all()

# The same router on LinuxCNC, reached through its linuxcncrsh (the sim board's twin of it): the
# clicked zero sent by MDI after confirm, read back by linuxcncrsh's POS_OFFSET.
linuxcnc = os.path.join(work, "placing-linuxcnc.toml")
with open(linuxcnc, "w") as f:
    f.write(open(placing).read().replace('firmware = "grbl"', 'firmware = "linuxcnc"', 1)
            .replace("[planar]\n", '[link]\nkind = "linuxcnc"\nurl = "cnc.local:5007"\n\n[planar]\n', 1)
            .replace("\n[touch_probe]\nclear_z_mm = -40.0\n", "\n"))  # grbl's probe cycle only
box, url = run.box(calbox, top, data, [], '[web]\npassword = "%s"\n' % password_hash(PASSWORD),
                   scenario=linuxcnc)
status, _, answer = request(url + "/api/action", "POST", {"action": "work-zero", "work_zero": zero_text,
                                                           "confirm": True}, password=PASSWORD)
if status != 200 or json.loads(answer)["command"] != command:
    run.fail("work zero on LinuxCNC: %d %s" % (status, answer[:200]))
run.wait_for("LinuxCNC's zero read back", lambda: any(
    line == "work zero: the controller's G54 zero at machine X%.3f Y%.3f (sent '%s', read back by "
    "linuxcncrsh's POS_OFFSET)" % (zero[0], zero[1], command)
    for line in get_json(url + "/api/status")["log"]), 30, box)
run.stop_all()
print("the stock's top probed %.3f mm (the twin's sheet %.2f)" % (top_mm, SHEET_MM))
print("the Place screen: bed view %dx%d at %.2f mm a pixel, zero clicked at %s, job drawn and "
      "compensated (%s)" % (size[0], size[1], a, zero_text, reply.split(": ", 2)[2][:80]))
