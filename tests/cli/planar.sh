#!/usr/bin/env bash
# The planar cycle on the command line (toolchain/planar_cycle.sh) with a half-size camera that
# the box calibrates from photos: the model from one photo of the drilled sheet takes a fresh
# job's holes to within the goal in the twin's truth.
set -euo pipefail
calbox="$1"; top="$2"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
bash "$top/toolchain/planar_cycle.sh" "$calbox" "$work" "$top/tests/scenarios/planar_small.toml" > "$work/log" 2>&1
cat "$work/log"
for f in camera.yaml plane.yaml holes.gcode holes.json holes.png holes_overlay.png measurements.json \
         result.json error_map.png firmware.txt holes_compensated.gcode verify.json; do
    [ -s "$work/$f" ] || { echo "missing $f"; exit 1; }
done
grep -q "143 holes measured, 0 missing, 0 extra blobs" "$work/log"
grep -q "x_pitch_rate       held: absorbed by x_scale" "$work/log"
/usr/bin/python3 -c "
import json, sys
v = json.load(open('$work/verify.json'))
r = json.load(open('$work/result.json'))
b, a = v['before'], v['after']
print('fresh holes: before %.4f mean %.4f worst; through the compensated G-code %.5f mean %.5f worst' % (
      b['mean_mm'], b['max_mm'], a['mean_mm'], a['max_mm']))
# The issue's bar: 95 %% less and under 0.05 mm mean; the README claims both here.
ok = b['mean_mm'] > 1.0 and a['mean_mm'] < 0.05 and a['mean_mm'] <= 0.05 * b['mean_mm']
# The seed's statistics table, before and after, in the result.
ok = ok and all(k in r['before'] and k in r['after'] for k in ('max_mm', 'q3_mm', 'median_mm', 'q1_mm', 'min_mm', 'mean_mm', 'std_mm'))
ok = ok and sum(1 for p in r['parameters'] if p['fitted']) == 6
sys.exit(0 if ok else 'planar verdict out of bounds')"
# The compensated job keeps the original's every non-move line: spindle, dwells, plunges.
for pattern in "^M3 S" "^G4 P" "^M5" "Z-2.000"; do
    [ "$(grep -c -- "$pattern" "$work/holes.gcode")" -eq "$(grep -c -- "$pattern" "$work/holes_compensated.gcode")" ] \
        || { echo "compensated job lost lines matching $pattern"; exit 1; }
done
echo "planar cycle complete"

# The appliance: one cycle on the router, the box keeping the error model; revert puts back
# what was in force before (none).
data="$work/box"
"$calbox" run --board sim --scenario "$top/tests/scenarios/planar_small.toml" --data "$data" --auto \
    > "$work/run.out" 2> "$work/run.err" < /dev/null
cat "$work/run.out"
grep -q "^before: .* mm mean" "$work/run.out"
grep -q "^after: through the error model " "$work/run.out"
grep -q "verified on the grid drilled through the model" "$work/run.err"
for f in planar-result.json cycle-0001-result.json cycle-0001-measurements.json cycle-0001-firmware.txt \
         cycle-0001-backup-result.json cycle-0001-verify-measurements.json; do
    [ -s "$data/$f" ] || { echo "appliance: missing $f"; exit 1; }
done
[ "$(cat "$data/cycle-0001-backup-result.json")" = "none" ]
grep -q '"schema": "calbox.planar-result/1"' "$data/planar-result.json"
"$calbox" revert --board sim --scenario "$top/tests/scenarios/planar_small.toml" --data "$data" 2> "$work/revert.err" < /dev/null
[ "$(cat "$data/planar-result.json")" = "none" ] || { echo "revert left the model in force"; exit 1; }
echo "planar appliance cycle and revert complete"

# A cartesian printer in the appliance: printed dots, the same cycle and goal.
data="$work/printer"
"$calbox" run --board sim --scenario "$top/tests/scenarios/planar_printer_small.toml" --data "$data" --auto \
    > "$work/printer.out" 2> "$work/printer.err" < /dev/null || { cat "$work/printer.err" | tail -5; exit 1; }
cat "$work/printer.out"
grep -q "^after: through the error model " "$work/printer.out"
[ -s "$data/planar-result.json" ]
echo "planar printer cycle complete"
