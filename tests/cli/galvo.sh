#!/usr/bin/env bash
# The galvo cycle on the command line (toolchain/galvo_cycle.sh) with a half-size camera that the
# box calibrates from photos: the table from one photo takes the scanner's marks to within the
# goal in the twin's truth, and a second pass through the table keeps them there.
set -euo pipefail
calbox="$1"; top="$2"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
bash "$top/toolchain/galvo_cycle.sh" "$calbox" "$work" "$top/tests/scenarios/galvo_small.toml" > "$work/log"
cat "$work/log"
for f in camera.yaml plane.yaml grid.gcode grid.json grid_preview.png grid.png grid_overlay.png \
         measurements.json result.json table.csv error_map.png verify.json grid_compensated.gcode \
         measurements2.json result2.json verify2.json; do
    [ -s "$work/$f" ] || { echo "missing $f"; exit 1; }
done
grep -q "961 of 961 marks measured (dark marks), 0 missing" "$work/log"
# 65 x 65 nodes, a comment and a header line.
[ "$(wc -l < "$work/table.csv")" -eq 4227 ]
/usr/bin/python3 -c "
import json, sys
v1 = json.load(open('$work/verify.json'))
v2 = json.load(open('$work/verify2.json'))
r2 = json.load(open('$work/result2.json'))
b, a1, a2 = v1['before'], v1['after'], v2['after']
print('before %.4f mean %.4f worst; after pass 1 %.5f mean %.5f worst; after pass 2 %.5f mean %.5f worst' % (
      b['mean_mm'], b['max_mm'], a1['mean_mm'], a1['max_mm'], a2['mean_mm'], a2['max_mm']))
# The issue's goal is 0.008 mean and 0.03 worst; the README claims 0.004 and 0.01 here.
ok = b['mean_mm'] > 0.05 and a1['mean_mm'] <= 0.004 and a1['max_mm'] <= 0.01
ok = ok and a2['mean_mm'] <= 0.004 and a2['max_mm'] <= 0.01 and r2['pass'] == 2
# The second pass measures the grid already corrected: what it sees is under the goal too.
ok = ok and r2['before']['mean_mm'] <= 0.008
sys.exit(0 if ok else 'galvo verdict out of bounds')"
# The compensated job keeps the original's non-move lines.
grep -c "^M3 S" "$work/grid.gcode" > "$work/m3_a"
grep -c "^M3 S" "$work/grid_compensated.gcode" > "$work/m3_b"
cmp -s "$work/m3_a" "$work/m3_b"
echo "galvo cycle complete"
