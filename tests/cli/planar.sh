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
# Where the job is: the frame stated, the output marked; a router's job without its work zero, a
# point past the travel and a job compensated already are refused, nothing written.
grep -q "^frame: job placed with --work-zero measured (G54 zero at machine X-300.000 Y-300.000 mm); the result measured with its zero at machine X-300.000 Y-300.000 mm (from the machine file)" "$work/log"
head -n 1 "$work/holes_compensated.gcode" | grep -q "^; calbox: compensated through result fnv1a64:[0-9a-f]\{16\} on 20"
refused() {  # refused WHAT-TO-SEE ARGS...: exit non-zero, that line on stderr, no output file
    local see="$1"; shift
    if "$calbox" compensate --result "$work/result.json" "$@" -o "$work/refused.gcode" 2> "$work/err"; then
        echo "compensated: $*"; exit 1
    fi
    grep -q -- "$see" "$work/err" || { cat "$work/err"; exit 1; }
    [ ! -e "$work/refused.gcode" ] || { echo "refused, yet wrote its output"; exit 1; }
}
refused "holes.gcode: a router's job is written around its work zero, which calbox cannot see: give --work-zero X,Y" "$work/holes.gcode"
printf 'G90\nG0 X0 Y0\nG1 X1000 Y-1000 F600\n' > "$work/far.gcode"
refused "far.gcode: line 3: the point X1000 Y-1000 is at machine X700 Y-1300 mm, beyond the machine's travel (X -300..0, Y -300..0 mm)" "$work/far.gcode" --work-zero measured
refused "holes_compensated.gcode: already compensated" "$work/holes_compensated.gcode" --work-zero measured
# A job written around a stock corner at machine (-250, -200): placed there, inside the travel.
printf 'G21 G90\nG0 X0 Y0\nG1 X100 Y50 F600\n' > "$work/stock.gcode"
"$calbox" compensate --result "$work/result.json" "$work/stock.gcode" --work-zero -250,-200 -o "$work/stock_compensated.gcode" > "$work/stock.out"
grep -q "G54 zero at machine X-250.000 Y-200.000 mm" "$work/stock.out"
# The bed in the machine's coordinates from the drilled sheet's photo: its size, its world file
# (read here as a GIS reads it: pixel size, then the top-left pixel's centre), the PNG's own
# header, and the refusals, nothing written by them.
"$calbox" view bed --camera "$work/camera.yaml" --plane "$work/plane.yaml" --result "$work/result.json" \
    "$work/holes.png" --stock-thickness 1.5 --mm-per-px 0.5 -o "$work/bed.png" > "$work/view.out"
cat "$work/view.out"
grep -q "bed.png: 600 x 600 px of X -300.000..0.000 Y -300.000..0.000 mm at 0.500 mm a pixel" "$work/view.out"
[ "$(tr '\n' ' ' < "$work/bed.pgw")" = "0.5 0 0 -0.5 -299.75 -0.25 " ] || { cat "$work/bed.pgw"; exit 1; }
/usr/bin/python3 -c "
import struct, sys
data = open('$work/bed.png', 'rb').read()
w, h, depth, colour = struct.unpack('>IIBB', data[16:26])
sys.exit(0 if data[:8] == b'\x89PNG\r\n\x1a\n' and (w, h, depth, colour) == (600, 600, 8, 2) else 'bed.png: %r' % ((w, h, depth, colour),))"
view_refused() {  # view_refused WHAT-TO-SEE ARGS...
    local see="$1"; shift
    if "$calbox" view bed --camera "$work/camera.yaml" --plane "$work/plane.yaml" "$@" 2> "$work/err"; then
        echo "viewed: $*"; exit 1
    fi
    grep -q -- "$see" "$work/err" || { cat "$work/err"; exit 1; }
    [ ! -e "$work/refused.png" ] && [ ! -e "$work/refused.pgw" ] || { echo "refused, yet wrote"; exit 1; }
}
view_refused "reaches beyond the machine's travel (X -300.000..0.000 Y -300.000..0.000 mm)" \
    --result "$work/result.json" "$work/holes.png" --area -350,-300,0,0 -o "$work/refused.png"
view_refused "bed.png: the photo is 600x600, the camera was calibrated at 2028x1520" \
    --result "$work/result.json" "$work/bed.png" -o "$work/refused.png"
view_refused "-o must name a .png" --result "$work/result.json" "$work/holes.png" -o "$work/refused.jpg"
view_refused "--area '1,2,3': give X0,Y0,X1,Y1" --result "$work/result.json" "$work/holes.png" --area 1,2,3 -o "$work/refused.png"
/usr/bin/python3 -c "
import json
r = json.load(open('$work/result.json'))
del r['placement']['bed_mirrored']
json.dump(r, open('$work/old_result.json', 'w'))"
view_refused "old_result.json: a result from before calbox recorded which way round the camera's bed lies" \
    --result "$work/old_result.json" "$work/holes.png" -o "$work/refused.png"
# The sheet on the bed: found, its corners written; a job placed at one of them and turned with
# it (the accuracy is test_bed_view's, against the twin's truth).
"$calbox" sim photo --scenario "$top/tests/scenarios/planar_small.toml" --sheet 50,60,210,150,2.7 \
    --thickness 3 -o "$work/sheet.png"
"$calbox" view stock --camera "$work/camera.yaml" --plane "$work/plane.yaml" --result "$work/result.json" \
    "$work/sheet.png" --stock-thickness 3 -o "$work/stock.json" --overlay "$work/stock.png" > "$work/stock.out"
cat "$work/stock.out"
grep -q "stock.json: a dark sheet 210.0[0-9] x 149.9[0-9] mm turned 2.8[0-9]* deg" "$work/stock.out" \
    || grep -q "stock.json: a dark sheet 210.0[0-9] x 150.0[0-9] mm turned 2.8[0-9]* deg" "$work/stock.out"
grep -q "^front-left  X-25[01].[0-9]* Y-24[01].[0-9]* mm +/-0.0[0-9]* (1 sigma)" "$work/stock.out"
grep -q '"schema": "calbox.stock/1"' "$work/stock.json"
printf 'G21 G90 G54\nG0 X10 Y10\nG1 Z-1 F300\nG1 X190 Y10 F600\nG0 Z5\n' > "$work/on_sheet.gcode"
"$calbox" compensate --result "$work/result.json" "$work/on_sheet.gcode" --work-zero camera \
    --stock "$work/stock.json" --corner front-left -o "$work/on_sheet_compensated.gcode" > "$work/placed.out"
grep -q "frame: job placed with the camera: .*stock.json's front-left corner at machine X-25[01].[0-9]* Y-24[01].[0-9]* mm (+/-0.0[0-9]*), the job turned 2.8[0-9]* deg with the sheet's front edge" "$work/placed.out" \
    || { cat "$work/placed.out"; exit 1; }
refused "--work-zero camera places the job at the sheet the camera found: give --stock stock.json" \
    "$work/on_sheet.gcode" --work-zero camera
refused "--stock is for --work-zero camera" "$work/on_sheet.gcode" --work-zero measured --stock "$work/stock.json"
refused "--corner 'middle' is no corner of a sheet" "$work/on_sheet.gcode" --work-zero camera \
    --stock "$work/stock.json" --corner middle
refused "--corner names the sheet's corner for --work-zero camera" "$work/on_sheet.gcode" --work-zero measured --corner front-left
printf 'G21 G90\nG55\nG0 X1 Y1\n' > "$work/g55.gcode"
refused "line 2: G55 in a job placed turned with the stock" "$work/g55.gcode" --work-zero camera --stock "$work/stock.json"
# Print and cut's marks (their accuracy is test_bed_view's): a photo without them, and marks
# not given as X,Y, are refused.
if "$calbox" view marks --camera "$work/camera.yaml" --plane "$work/plane.yaml" --result "$work/result.json" \
    "$work/sheet.png" --marks "0,0;160,0;0,110" -o "$work/marks.json" 2> "$work/err"; then
    echo "marks found on a sheet without any"; exit 1
fi
grep -q "sheet.png: the photo shows [0-9]* round marks 5.0 mm across, the drawing has 3" "$work/err" || { cat "$work/err"; exit 1; }
if "$calbox" view marks --camera "$work/camera.yaml" --plane "$work/plane.yaml" --result "$work/result.json" \
    "$work/sheet.png" --marks "0,0;160" -o "$work/marks.json" 2> "$work/err"; then exit 1; fi
grep -q -- "--marks '0,0;160': give each mark's X,Y in the drawing" "$work/err" || { cat "$work/err"; exit 1; }
if "$calbox" view marks --camera "$work/camera.yaml" --plane "$work/plane.yaml" --result "$work/result.json" \
    "$work/sheet.png" --mark-kind markers --marks "0,0;160,0;0,110" -o "$work/marks.json" 2> "$work/err"; then exit 1; fi
grep -q -- "give each marker as ID:X,Y" "$work/err" || { cat "$work/err"; exit 1; }
if "$calbox" view marks --camera "$work/camera.yaml" --plane "$work/plane.yaml" --result "$work/result.json" \
    "$work/sheet.png" --mark-line 0.5 --marks "0,0;160,0;0,110" -o "$work/marks.json" 2> "$work/err"; then exit 1; fi
grep -q -- "--mark-line goes with --mark-kind crosses" "$work/err" || { cat "$work/err"; exit 1; }
if "$calbox" view marks --camera "$work/camera.yaml" --plane "$work/plane.yaml" --result "$work/result.json" \
    "$work/sheet.png" --mark-kind crosses --mark-line 4 --marks "0,0;160,0;0,110" -o "$work/marks.json" 2> "$work/err"; then exit 1; fi
grep -q "crosses with bars 4.00 mm wide: give 0.1 mm to a quarter of their 5.00 mm span" "$work/err" || { cat "$work/err"; exit 1; }
if "$calbox" view marks --camera "$work/camera.yaml" --plane "$work/plane.yaml" --result "$work/result.json" \
    "$work/sheet.png" --mark-kind markers --marks "3:0,0;7:160,0;11:0,110" -o "$work/marks.json" 2> "$work/err"; then exit 1; fi
grep -q "sheet.png: marker 3 (DICT_4X4_50, drawing X0.00 Y0.00) is not in the photo" "$work/err" || { cat "$work/err"; exit 1; }
[ ! -e "$work/marks.json" ]
echo "planar cycle complete"

# The appliance: one cycle on the router, the box keeping the error model; revert puts back
# what was in force before (none). Then (the scenario's [placement], examples/router_stock.toml's)
# a sheet laid on the spoilboard where the box does not know it: photographed, its corner found,
# examples/router_stock.gcode drilled there, each hole judged against where the job meant it on
# the sheet.
data="$work/box"
"$calbox" run --board sim --scenario "$top/tests/scenarios/router_stock_small.toml" --data "$data" --auto \
    > "$work/run.out" 2> "$work/run.err" < /dev/null || { cat "$work/run.out"; tail -5 "$work/run.err"; exit 1; }
cat "$work/run.out"
grep -q "^before: .* mm mean" "$work/run.out"
grep -q "^after: through the error model " "$work/run.out"
grep -q "^placement: frame: job placed with the camera: placement-stock.json's front-left corner at machine X" "$work/run.out"
/usr/bin/python3 -c "
import re, sys
m = re.search(r'placement: the sheet.s front-left corner, turned ([0-9.-]+) deg in the machine.s axes \(3.200 on the bed.s\); 5 holes ([0-9.]+) mm mean, ([0-9.]+) mm worst', open('$work/run.out').read())
sys.exit(0 if m and float(m.group(2)) < 0.05 and float(m.group(3)) < 0.1 else 'placement: %s' % (m.groups() if m else None))"
[ -s "$data/placement-stock.json" ] && [ -s "$data/placement-job-compensated.nc" ]
# A goal the placement cannot meet is a failed run, saying by how much.
sed 's/^goal_mm = 0.1$/goal_mm = 0.001/' "$top/tests/scenarios/router_stock_small.toml" \
    | sed "s|^job = .*|job = \"$top/examples/router_stock.gcode\"|" > "$work/stock_miss.toml"
if "$calbox" run --board sim --scenario "$work/stock_miss.toml" --data "$work/miss" --auto \
    > "$work/miss.out" 2> "$work/miss.err" < /dev/null; then
    echo "a placement past its goal exited 0"; exit 1
fi
grep -q "the placement goal is not met: a hole 0.0[0-9]* mm from where the job meant it on the sheet (goal 0.001 mm)" "$work/miss.err" \
    || { tail -3 "$work/miss.err"; exit 1; }
grep -q "verified on the grid drilled through the model" "$work/run.err"
for f in planar-result.json cycle-0001-result.json cycle-0001-measurements.json cycle-0001-firmware.txt \
         cycle-0001-backup-result.json cycle-0001-verify-measurements.json cycle-0001-bed-view.png \
         cycle-0001-bed-view.pgw; do
    [ -s "$data/$f" ] || { echo "appliance: missing $f"; exit 1; }
done
# The bed in the machine's coordinates in the records (and so on the web page's Result screen):
# the travel 750 pixels across, its top-left pixel's centre at machine X-299.8 Y-0.2.
[ "$(tr '\n' ' ' < "$data/cycle-0001-bed-view.pgw")" = "0.4 0 0 -0.4 -299.8 -0.2 " ] \
    || { cat "$data/cycle-0001-bed-view.pgw"; exit 1; }
[ "$(cat "$data/cycle-0001-backup-result.json")" = "none" ]
grep -q '"schema": "calbox.planar-result/1"' "$data/planar-result.json"
# The frame the box measured in, as grbl reported it before the sheet was drilled.
grep -q "the controller's G54 zero (\$#): machine X-300.000 Y-300.000 mm" "$work/run.err"
/usr/bin/python3 -c "
import json, sys
f = json.load(open('$data/planar-result.json'))['frame']
sys.exit(0 if f['work_zero_mm'] == [-300, -300] and f['work_zero_from'] == \"the controller's G54 (\$#)\" and f['travel_mm'] == [-300, -300, 0, 0] else 'frame: %s' % f)"
"$calbox" revert --board sim --scenario "$top/tests/scenarios/planar_small.toml" --data "$data" 2> "$work/revert.err" < /dev/null
[ "$(cat "$data/planar-result.json")" = "none" ] || { echo "revert left the model in force"; exit 1; }
# A job through the reverted correction: none is in force, said so.
if "$calbox" compensate --result "$data/planar-result.json" "$work/stock.gcode" --work-zero -250,-200 -o "$work/none.gcode" 2> "$work/err"; then
    echo "compensated through a reverted correction"; exit 1
fi
grep -q "planar-result.json: no correction in force" "$work/err" || { cat "$work/err"; exit 1; }
echo "planar appliance cycle and revert complete"

# A cartesian printer in the appliance: printed dots, the same cycle and goal.
data="$work/printer"
"$calbox" run --board sim --scenario "$top/tests/scenarios/planar_printer_small.toml" --data "$data" --auto \
    > "$work/printer.out" 2> "$work/printer.err" < /dev/null || { cat "$work/printer.err" | tail -5; exit 1; }
cat "$work/printer.out"
grep -q "^after: through the error model " "$work/printer.out"
[ -s "$data/planar-result.json" ]
echo "planar printer cycle complete"
