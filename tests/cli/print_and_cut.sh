#!/usr/bin/env bash
# examples/laser_print_and_cut.toml end to end, as the README runs it: the gantry laser calibrated
# from its burned grid, then a printed card laid where the box does not know it; the box finds the
# four marks, places the cut by them and compensates it; the judge runs the placed cut on the
# twin's laser against the printed line. Then the same card with a goal the cut cannot meet (exit
# 1, saying by how much), and the scenario's refusals.
set -euo pipefail
calbox="$1"; top="$2"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
"$calbox" run --board sim --auto --scenario "$top/examples/laser_print_and_cut.toml" \
    --data "$work/box" > "$work/run.out" 2> "$work/run.err" < /dev/null \
    || { cat "$work/run.out"; tail -5 "$work/run.err"; exit 1; }
cat "$work/run.out"
# The laser's own cycle: the error norm from about a quarter millimetre to under 0.05 mm mean.
/usr/bin/python3 - "$work/run.out" <<'PY'
import re, sys
out = open(sys.argv[1]).read()
before = re.search(r'^before: ([0-9.]+) mm mean, ([0-9.]+) mm worst', out, re.M)
after = re.search(r'^after: through the error model ([0-9.]+) mm mean, ([0-9.]+) mm worst', out, re.M)
cut = re.search(r'^placement: 4 marks, the drawing turned ([0-9.-]+) deg, scale ([0-9.]+), worst mark '
                r'([0-9.]+) mm; the cut ([0-9.]+) mm mean, ([0-9.]+) mm worst from the printed line '
                r'over ([0-9]+) points \(goal 0.100 mm\)$', out, re.M)
if not (before and after and cut):
    sys.exit('print and cut: lines missing')
b, a = float(before.group(1)), float(after.group(1))
turn, scale, mark, mean, worst, points = (float(g) for g in cut.groups())
print('laser %.4f -> %.5f mm mean; card turned %.3f deg, scale %.5f, worst mark %.4f mm; '
      'the cut %.4f mean %.4f worst over %d points' % (b, a, turn, scale, mark, mean, worst, points))
ok = b > 0.2 and a < 0.05 and a <= 0.05 * b
# The card lies turned -3.6 deg on the bed, the printer stretched it by 0.2 % one way and 0.14 %
# the other: the box's fit says so (its one scale between the two; the machine's own axes lie a
# little turned on the bed, out of square by 0.3 deg), and the marks' residuals hold the rest.
ok = ok and -3.8 < turn < -3.3 and 1.0014 <= scale <= 1.002 and 0.005 < mark < 0.05
# The issue's bar: the cut within 0.1 mm of the printed line everywhere, 0.05 mm on the mean.
ok = ok and worst < 0.1 and mean < 0.05 and points > 1000
sys.exit(0 if ok else 'print and cut out of bounds')
PY
grep -q "^placement: frame: job placed with the printed marks: placement-marks.json's 4 marks" "$work/run.out"
[ -s "$work/box/placement-marks.json" ] && [ -s "$work/box/placement-job-compensated.nc" ]
grep -q '"schema": "calbox.registration/1"' "$work/box/placement-marks.json" \
    || { head -3 "$work/box/placement-marks.json"; exit 1; }
# The placed cut keeps the laser's words: power on before the line, off after it.
grep -q "^M4 S800" "$work/box/placement-job-compensated.nc"
grep -q "^M5" "$work/box/placement-job-compensated.nc"

# A goal the cut cannot meet is a failed run, saying by how much.
sed -e 's/^goal_mm = 0.1$/goal_mm = 0.005/' \
    -e "s|^job = .*|job = \"$top/examples/laser_print_and_cut.gcode\"|" \
    "$top/examples/laser_print_and_cut.toml" > "$work/miss.toml"
if "$calbox" run --board sim --auto --scenario "$work/miss.toml" --data "$work/miss" \
    > "$work/miss.out" 2> "$work/miss.err" < /dev/null; then
    echo "a print and cut past its goal exited 0"; exit 1
fi
grep -q "the placement goal is not met: the cut 0.0[0-9]* mm from the printed line (goal 0.005 mm)" "$work/miss.err" \
    || { tail -3 "$work/miss.err"; exit 1; }

# The scenario's refusals: a card's key beside a sheet's, three marks' worth of numbers that are
# not pairs, ink lighter than the card, a card under a router (whose cut no judge here runs).
refused() {
    local name="$1" message="$2"
    if "$calbox" run --board sim --auto --scenario "$work/$name.toml" --data "$work/$name" \
        > /dev/null 2> "$work/$name.err" < /dev/null; then
        echo "$name: accepted"; exit 1
    fi
    grep -qF "$message" "$work/$name.err" || { echo "$name:"; tail -2 "$work/$name.err"; exit 1; }
}
sed 's/^goal_mm = 0.1$/goal_mm = 0.1\nsheet_width_mm = 200.0/' "$top/examples/laser_print_and_cut.toml" > "$work/both.toml"
refused both "[placement] sheet_width_mm"
sed 's/^marks_mm = .*/marks_mm = [0.0, 0.0, 130.0, 0.0, 130.0]/' "$top/examples/laser_print_and_cut.toml" > "$work/odd.toml"
refused odd "[placement] marks_mm"
sed 's/^mark_diameter_mm = 5.0$/mark_diameter_mm = 5.0\nink_albedo = 0.9/' "$top/examples/laser_print_and_cut.toml" > "$work/ink.toml"
refused ink "[placement] ink_albedo: the ink must be darker than the card"
sed -e 's/^kind = "laser"/kind = "router"/' -e 's/^\[truth.cartesian\]/[truth.router]\nseed = 1\n[unread]/' \
    -e "s|^job = .*|job = \"$top/examples/laser_print_and_cut.gcode\"|" \
    "$top/examples/laser_print_and_cut.toml" | sed '/^\[unread\]/,/^$/d' > "$work/router.toml"
refused router "[placement] places a router's job on a sheet (sheet_*) or a laser's cut on a printed card (marks_mm); this is a router with a card"
echo "print and cut complete"
