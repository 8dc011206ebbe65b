#!/usr/bin/env bash
# The most complete cycle that works today, on the digital twin: a delta printer whose true rods
# are 1 mm longer than its firmware believes prints a 40 mm square; the camera photographs it and
# a chessboard lying on the bed. Prints the figures and where the files are.
#   usage: toolchain/sim_cycle.sh CALBOX_BINARY [OUTPUT_DIR]
set -euo pipefail
calbox="${1:?usage: sim_cycle.sh CALBOX_BINARY [OUTPUT_DIR]}"
top="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="${2:-$top/out}"
mkdir -p "$out"
scenario="$top/examples/delta_rod_error.toml"

echo "== print: 40 mm square on a delta with a hidden +1 mm rod error ($scenario)"
"$calbox" sim print --scenario "$scenario" "$top/examples/square.gcode" -o "$out/print.json"
echo "== photo of the print (4056x3040, tilted about 5 degrees, blur and noise on)"
"$calbox" sim photo --scenario "$scenario" --print "$out/print.json" -o "$out/print.png" --truth "$out/print_truth.json"
echo "== photo of a 9x6 chessboard (20 mm squares) lying on the bed"
"$calbox" sim photo --scenario "$scenario" --board chessboard:9x6@20 --on-bed -80,50,0 \
    -o "$out/chessboard.png" --truth "$out/chessboard_truth.json"
echo "== a drawing made into a job and printed: examples/ring_star.svg, 40 mm across"
"$calbox" target svg "$top/examples/ring_star.svg" --machine "$top/examples/delta.toml" --fit 40 \
    -o "$out/ring_star.gcode" --preview "$out/ring_star_preview.png"
"$calbox" sim print --scenario "$scenario" "$out/ring_star.gcode" -o "$out/ring_star_print.json" | tail -n 1
"$calbox" sim photo --scenario "$scenario" --print "$out/ring_star_print.json" -o "$out/ring_star.png"
echo "== the delta target, printed by the twin with the +1 mm rod error, photographed and read back"
"$calbox" target delta --machine "$top/examples/delta.toml" -o "$out/target.gcode" --preview "$out/target_preview.png" \
    --describe "$out/target.json"
"$calbox" sim print --scenario "$scenario" "$out/target.gcode" -o "$out/target_print.json" | tail -n 1
"$calbox" sim photo --scenario "$scenario" --print "$out/target_print.json" -o "$out/target.png"
"$calbox" detect markers "$out/target.png" -o "$out/target_detections.json" --overlay "$out/target_overlay.png"
echo "== ... measured from the photo (true camera, bed plane from the chessboard photo) and fitted"
"$calbox" sim camera --scenario "$scenario" -o "$out/camera.yaml"
"$calbox" camera plane --camera "$out/camera.yaml" --pattern chessboard:9x6@20 "$out/chessboard.png" -o "$out/plane.yaml"
"$calbox" measure delta --camera "$out/camera.yaml" --plane "$out/plane.yaml" --machine "$top/examples/delta.toml" \
    "$out/target.png" -o "$out/target_measurements.json" --overlay "$out/target_errors.png"
"$calbox" solve delta --machine "$top/examples/delta.toml" --measurements "$out/target_measurements.json" \
    -o "$out/target_result.json"
echo "== delta fit: a printer off in rods, trims, radius, tower angles and endstops (examples/delta_errors.toml)"
"$calbox" sim measurements --scenario "$top/examples/delta_errors.toml" -o "$out/measurements.json" --probe "$out/heights.csv"
"$calbox" solve delta --machine "$top/examples/delta.toml" --measurements "$out/measurements.json" \
    --probe "$out/heights.csv" -o "$out/result.json"
"$calbox" solve delta --machine "$top/examples/delta.toml" --measurements "$out/measurements.json" \
    --method classic -o "$out/result_classic.json" | head -n 1
echo "== files in $out: print.json print.png print_truth.json chessboard.png chessboard_truth.json"
echo "   ring_star.gcode ring_star_preview.png ring_star_print.json ring_star.png"
echo "   target.gcode target_preview.png target.json target.png target_detections.json target_overlay.png"
echo "   camera.yaml plane.yaml target_measurements.json target_errors.png target_result.json"
echo "   measurements.json heights.csv result.json result_classic.json"
