#!/usr/bin/env bash
# The galvo cycle one command at a time on the twin: the circle grid burned by a scanner with
# hidden field distortion, the box's camera calibrated from board views and the platform's plane
# from a board lying on it, the grid measured, the correction table built and judged in the twin's
# truth, then a second pass burned through the table and the table refined.
#   toolchain/galvo_cycle.sh CALBOX OUT_DIR [SCENARIO]   (default: examples/galvo_cycle.toml)
set -euo pipefail
calbox="$1"; out="$2"
top="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
scenario="${3:-$top/examples/galvo_cycle.toml}"
machine="$top/examples/galvo_scanner.toml"
mkdir -p "$out"
echo "== the box's set-up: the camera from eight views of an 11x8 chessboard (8 mm squares), the platform from a 15x11 board lying on it"
i=0
for pose in 0,0,0,-40,-28,330 18,0,0,-40,-26,320 -18,0,0,-40,-30,335 0,18,0,-42,-28,325 0,-18,0,-38,-28,335 \
            12,12,5,-40,-28,330 -12,12,-5,-40,-28,325 12,-12,10,-40,-28,340; do
    i=$((i + 1))
    "$calbox" sim photo --scenario "$scenario" --board chessboard:11x8@8 --pose "$pose" -o "$out/view_$i.png"
done
"$calbox" camera calibrate --pattern chessboard:11x8@8 "$out"/view_*.png -o "$out/camera.yaml" | tail -n 1
"$calbox" sim photo --scenario "$scenario" --board chessboard:15x11@8 --on-bed -56,40,0 -o "$out/plane_board.png"
"$calbox" camera plane --camera "$out/camera.yaml" --pattern chessboard:15x11@8 "$out/plane_board.png" -o "$out/plane.yaml"
echo "== pass 1: the grid burned as commanded"
"$calbox" target galvo --machine "$machine" -o "$out/grid.gcode" --describe "$out/grid.json" --preview "$out/grid_preview.png"
"$calbox" sim print --scenario "$scenario" "$out/grid.gcode" -o "$out/grid_print.json" | tail -n 1
"$calbox" sim photo --scenario "$scenario" --print "$out/grid_print.json" -o "$out/grid.png"
"$calbox" measure galvo --camera "$out/camera.yaml" --plane "$out/plane.yaml" --machine "$machine" \
    "$out/grid.png" -o "$out/measurements.json" --overlay "$out/grid_overlay.png"
"$calbox" solve galvo --machine "$machine" --measurements "$out/measurements.json" -o "$out/result.json" \
    --table-csv "$out/table.csv" --error-map "$out/error_map.png"
"$calbox" sim verify --scenario "$scenario" --result "$out/result.json" -o "$out/verify.json"
echo "== pass 2: the grid burned through the table, measured again, the table refined"
"$calbox" compensate --result "$out/result.json" "$out/grid.gcode" -o "$out/grid_compensated.gcode"
"$calbox" sim print --scenario "$scenario" "$out/grid_compensated.gcode" -o "$out/grid2_print.json" | tail -n 1
"$calbox" sim photo --scenario "$scenario" --print "$out/grid2_print.json" -o "$out/grid2.png"
"$calbox" measure galvo --camera "$out/camera.yaml" --plane "$out/plane.yaml" --machine "$machine" \
    "$out/grid2.png" -o "$out/measurements2.json"
"$calbox" solve galvo --machine "$machine" --measurements "$out/measurements2.json" \
    --burned-through "$out/result.json" -o "$out/result2.json"
"$calbox" sim verify --scenario "$scenario" --result "$out/result2.json" -o "$out/verify2.json"
