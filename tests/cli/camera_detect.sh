#!/usr/bin/env bash
# calbox camera and calbox detect on twin-rendered photos, end to end through files.
set -euo pipefail
calbox="$1"; top="$2"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
cat > "$work/scene.toml" <<'TOML'
[machine]
kind = "delta"
[delta]
diagonal_rod_mm = 250.0
radius_mm = 140.0
[camera]
width_px = 1280
height_px = 960
fx = 1100.0
distortion = [-0.1, 0.05, 0.0, 0.0, 0.0]
position_mm = [0.0, -30.0, 420.0]
look_at_mm = [0.0, 0.0, 0.0]
[photo]
noise_sigma_dn = 2.0
blur_sigma_px = 0.7
TOML
# Eight views of a 9x6 chessboard (20 mm) from different angles (rotation vector in degrees).
i=0
for pose in "0,0,0,-80,-50,420" "20,0,0,-80,-40,430" "-20,5,0,-90,-50,420" "0,25,5,-60,-50,440" \
            "0,-25,-5,-100,-50,420" "15,15,10,-70,-60,450" "-15,-15,-10,-90,-40,410" "10,-20,20,-60,-70,460"; do
    "$calbox" sim photo --scenario "$work/scene.toml" --board chessboard:9x6@20 --pose "$pose" -o "$work/view$i.png"
    i=$((i + 1))
done
"$calbox" camera calibrate --pattern chessboard:9x6@20 "$work"/view*.png "$work/missing_board.png" -o "$work/camera.yaml" 2> "$work/err" && exit 1
grep -q "cannot read image" "$work/err"
"$calbox" sim photo --scenario "$work/scene.toml" --board charuco:5x7@20/14:DICT_6X6_250 --pose 0,0,0,-50,-70,420 -o "$work/not_a_chessboard.png"
"$calbox" camera calibrate --pattern chessboard:9x6@20 "$work"/view*.png "$work/not_a_chessboard.png" -o "$work/camera.yaml" | tee "$work/calibrate.log"
grep -q "skipped $work/not_a_chessboard.png: board not found" "$work/calibrate.log"
grep -qE "RMS 0\.[01][0-9]* px over 8 views" "$work/calibrate.log"
grep -q "camera_matrix" "$work/camera.yaml"
# fx within 1 % of the truth from eight views.
fx=$(sed -n 's/.*fx \([0-9.]*\) .*/\1/p' "$work/calibrate.log")
awk -v fx="$fx" 'BEGIN { exit !(fx > 1089 && fx < 1111) }'

"$calbox" sim photo --scenario "$work/scene.toml" --board chessboard:9x6@20 --on-bed -80,50,0 --thickness 2 -o "$work/bed.png"
"$calbox" camera plane --camera "$work/camera.yaml" --pattern chessboard:9x6@20 --thickness 2 "$work/bed.png" -o "$work/plane.yaml"
grep -q "bed_rvec" "$work/plane.yaml"
grep -q "board_thickness_mm: 2" "$work/plane.yaml"

"$calbox" sim photo --scenario "$work/scene.toml" --board aruco:4x3@30/8:DICT_4X4_50 --on-bed -70,45,10 -o "$work/markers.png" --truth "$work/truth.json"
"$calbox" detect markers "$work/markers.png" -o "$work/detections.json" --overlay "$work/overlay.png"
grep -q '"calbox.detections/1"' "$work/detections.json"
[ "$(grep -c '"id"' "$work/detections.json")" -eq 12 ]
[ "$(grep -c '"refined": true' "$work/detections.json")" -eq 12 ]
grep -q '"unrefined": 0' "$work/detections.json"
"$calbox" detect markers "$work/markers.png" --no-refine | grep -q '"unrefined": 12'
[ -s "$work/overlay.png" ]
"$calbox" detect markers "$work/markers.png" | grep -q '"markers"'   # JSON on standard output
# AprilTag's own detector for an AprilTag family; an unknown name lists both kinds.
"$calbox" sim photo --scenario "$work/scene.toml" --board aruco:4x3@30/8:DICT_APRILTAG_36h11 --on-bed -70,45,10 -o "$work/tags.png"
"$calbox" detect markers "$work/tags.png" --dict tag36h11 -o "$work/tags.json"
[ "$(grep -c '"refined": true' "$work/tags.json")" -eq 12 ]
if "$calbox" detect markers "$work/tags.png" --dict tag99h1 2> "$work/dict.err"; then exit 1; fi
grep -q "libapriltag's tag36h11" "$work/dict.err"
"$calbox" detect chessboard "$work/bed.png" --pattern chessboard:9x6@20 -o "$work/corners.json"
grep -q '"corners"' "$work/corners.json"
"$calbox" sim photo --scenario "$work/scene.toml" --board acircles:4x11@8 --on-bed -40,50,0 -o "$work/dots.png"
"$calbox" detect circles "$work/dots.png" --pattern acircles:4x11@8 -o "$work/dots.json"
grep -q '"centres"' "$work/dots.json"
echo "camera and detect commands work end to end"
