#!/usr/bin/env bash
# The main job, on the digital twin: a delta printer whose true rods are 1 mm longer than its
# firmware believes prints a 40 mm square and a drawing, photographed; then the whole delta cycle
# on a printer off in every parameter: target, print, photo, measure, fit, correction sent to the
# twin and judged in its truth, the classic bar method beside it. Prints the figures and where the
# files are.
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
cycle="$top/examples/delta_cycle.toml"
printer="$top/examples/delta_printer.toml"
echo "== the delta cycle: a printer off in every parameter ($cycle) prints the delta target"
"$calbox" target delta --machine "$printer" -o "$out/target.gcode" --preview "$out/target_preview.png" \
    --describe "$out/target.json"
"$calbox" sim print --scenario "$cycle" "$out/target.gcode" -o "$out/target_print.json" | tail -n 1
echo "== ... photographed once the bed has cooled to 30 C, with a chessboard photo for the bed plane"
"$calbox" sim photo --scenario "$cycle" --print "$out/target_print.json" -o "$out/target.png"
"$calbox" sim photo --scenario "$cycle" --board chessboard:9x6@20 --on-bed -80,50,0 -o "$out/cycle_chessboard.png"
"$calbox" detect markers "$out/target.png" -o "$out/target_detections.json" --overlay "$out/target_overlay.png"
"$calbox" sim camera --scenario "$cycle" -o "$out/camera.yaml"
"$calbox" camera plane --camera "$out/camera.yaml" --pattern chessboard:9x6@20 "$out/cycle_chessboard.png" -o "$out/plane.yaml"
echo "== ... measured (markers and bars), fitted, and the correction sent to the twin and judged in its truth"
"$calbox" measure delta --camera "$out/camera.yaml" --plane "$out/plane.yaml" --machine "$printer" \
    "$out/target.png" -o "$out/target_measurements.json" --overlay "$out/target_errors.png"
"$calbox" solve delta --machine "$printer" --measurements "$out/target_measurements.json" -o "$out/target_result.json"
"$calbox" sim verify --scenario "$cycle" --result "$out/target_result.json" -o "$out/target_verify.json"
echo "== ... the seed paper's classic rod correction from the same bars, judged the same way"
"$calbox" solve delta --machine "$printer" --measurements "$out/target_measurements.json" --method classic \
    -o "$out/target_result_classic.json" | head -n 1
"$calbox" sim verify --scenario "$cycle" --result "$out/target_result_classic.json" | tail -n 1
echo "== delta fit: a printer off in rods, trims, radius, tower angles and endstops (examples/delta_errors.toml)"
"$calbox" sim measurements --scenario "$top/examples/delta_errors.toml" -o "$out/measurements.json" --probe "$out/heights.csv"
"$calbox" solve delta --machine "$top/examples/delta.toml" --measurements "$out/measurements.json" \
    --probe "$out/heights.csv" -o "$out/result.json"
"$calbox" solve delta --machine "$top/examples/delta.toml" --measurements "$out/measurements.json" \
    --method classic -o "$out/result_classic.json" | head -n 1
echo "== files in $out: print.json print.png print_truth.json chessboard.png chessboard_truth.json"
echo "   ring_star.gcode ring_star_preview.png ring_star_print.json ring_star.png"
echo "   target.gcode target_preview.png target.json target_print.json target.png cycle_chessboard.png"
echo "   target_detections.json target_overlay.png camera.yaml plane.yaml target_measurements.json"
echo "   target_errors.png target_result.json target_verify.json target_result_classic.json"
echo "   measurements.json heights.csv result.json result_classic.json"
