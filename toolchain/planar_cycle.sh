#!/usr/bin/env bash
# The planar (router) cycle one command at a time on the twin: the hole grid drilled by a router
# with hidden quasi-static errors, the box's camera calibrated from board views and the
# spoilboard's plane from a board lying on it, the holes measured, the error model fitted, and a
# fresh job judged in the twin's truth as commanded and through the compensated G-code.
#   toolchain/planar_cycle.sh CALBOX OUT_DIR [SCENARIO]   (default: examples/planar_cycle.toml)
set -euo pipefail
calbox="$1"; out="$2"
top="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
scenario="${3:-$top/examples/planar_cycle.toml}"
machine="$top/examples/router.toml"
mkdir -p "$out"
echo "== the box's set-up: the camera from eight views of an 11x8 chessboard (20 mm squares), the spoilboard from a 15x11 board lying on it"
i=0
for pose in 0,0,0,-100,-70,520 18,0,0,-100,-66,500 -18,0,0,-100,-74,530 0,18,0,-104,-70,510 \
            0,-18,0,-96,-70,530 12,12,5,-100,-70,520 -12,12,-5,-100,-70,510 12,-12,10,-100,-70,540; do
    i=$((i + 1))
    "$calbox" sim photo --scenario "$scenario" --board chessboard:11x8@20 --pose "$pose" -o "$out/view_$i.png"
done
"$calbox" camera calibrate --pattern chessboard:11x8@20 "$out"/view_*.png -o "$out/camera.yaml" | tail -n 1
"$calbox" sim photo --scenario "$scenario" --board chessboard:15x11@15 --on-bed 45,235,0 -o "$out/plane_board.png"
"$calbox" camera plane --camera "$out/camera.yaml" --pattern chessboard:15x11@15 "$out/plane_board.png" -o "$out/plane.yaml"
echo "== the sheet drilled as commanded, photographed, measured, solved"
"$calbox" target planar --machine "$machine" -o "$out/holes.gcode" --describe "$out/holes.json"
"$calbox" sim print --scenario "$scenario" "$out/holes.gcode" -o "$out/holes_print.json" | tail -n 1
"$calbox" sim photo --scenario "$scenario" --print "$out/holes_print.json" -o "$out/holes.png"
"$calbox" measure planar --camera "$out/camera.yaml" --plane "$out/plane.yaml" --machine "$machine" \
    "$out/holes.png" -o "$out/measurements.json" --overlay "$out/holes_overlay.png"
"$calbox" solve planar --machine "$machine" --measurements "$out/measurements.json" -o "$out/result.json" \
    --error-map "$out/error_map.png" --firmware "$out/firmware.txt"
echo "== a job compensated, and a fresh job judged in the twin's truth"
"$calbox" compensate --result "$out/result.json" "$out/holes.gcode" -o "$out/holes_compensated.gcode" \
    --work-zero measured
"$calbox" sim verify --scenario "$scenario" --result "$out/result.json" -o "$out/verify.json"
