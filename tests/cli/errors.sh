#!/usr/bin/env bash
# Bad input to calbox gives exactly one line on stderr and a non-zero exit, and writes nothing.
set -u
calbox="$1"; top="$2"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
failures=0
scenario="$top/examples/delta_rod_error.toml"

# A library's own words never reach the user: OpenCV's exceptions and warnings, libjpeg's, an
# uncaught exception's. Every refusal below is checked for them.
refusals=0
no_library_text() {  # no_library_text WHAT (reads $work/err)
    refusals=$((refusals + 1))
    if grep -qE 'OpenCV\(|Assertion failed|Premature end of JPEG|Corrupt JPEG|libpng|terminate called|what\(\):|\[ WARN:' "$work/err"; then
        echo "FAIL: $1: a library's own text reached the user:"; sed 's/^/    /' "$work/err"
        failures=$((failures + 1))
    fi
}

expect_error() {  # expect_error REGEX ARGS...
    local regex="$1"; shift
    "$calbox" "$@" > "$work/out" 2> "$work/err" < /dev/null
    local status=$?
    local lines; lines=$(wc -l < "$work/err")
    if [ "$status" -eq 0 ] || [ "$lines" -ne 1 ] || ! grep -qE -- "$regex" "$work/err"; then
        echo "FAIL: calbox $* -> exit $status, stderr:"; sed 's/^/    /' "$work/err"
        failures=$((failures + 1))
    fi
    no_library_text "calbox $*"
    if [ -e "$work/result" ]; then
        echo "FAIL: calbox $* left an output file behind"; failures=$((failures + 1)); rm -f "$work/result"
    fi
}

printf 'G28\nG1 X1 Y1\n' > "$work/ok.gcode"
printf 'G28\nG29\n' > "$work/unknown.gcode"
printf 'G28\nG1 X400 Y0 Z0\n' > "$work/reach.gcode"
printf 'G1 X10 Y10\n' > "$work/unhomed.gcode"
printf 'G28\nG1 X1.2.3\n' > "$work/badnumber.gcode"
printf '[machine]\nkind = "delta"\n[delta]\nradius_mm = "wide"\n' > "$work/bad.toml"
printf '[machine\nkind = "delta"\n' > "$work/syntax.toml"
printf '[machine]\nkind = "delta"\n[delta]\n' > "$work/nocamera.toml"
printf '{"schema": "something else"}' > "$work/wrong.json"

expect_error "unknown command G29" sim print --scenario "$scenario" "$work/unknown.gcode" -o "$work/result"
expect_error "line 2: .*out of reach" sim print --scenario "$scenario" "$work/reach.gcode" -o "$work/result"
expect_error "line 1: move before homing" sim print --scenario "$scenario" "$work/unhomed.gcode" -o "$work/result"
expect_error "bad number '1.2.3'" sim print --scenario "$scenario" "$work/badnumber.gcode" -o "$work/result"
expect_error "radius_mm: must be a number" sim print --scenario "$work/bad.toml" "$work/ok.gcode" -o "$work/result"
expect_error "syntax.toml:[0-9]+:" sim print --scenario "$work/syntax.toml" "$work/ok.gcode" -o "$work/result"
expect_error "cannot read job" sim print --scenario "$scenario" "$work/missing.gcode" -o "$work/result"
expect_error "^calbox: sim print: -o is required \\(see calbox sim print --help\\)$" sim print --scenario "$scenario" "$work/ok.gcode"
expect_error "no \[camera\]" sim photo --scenario "$work/nocamera.toml" --board chessboard:9x6@20 --pose 0,0,0,0,0,400 -o "$work/result"
expect_error "not a print record" sim photo --scenario "$scenario" --print "$work/wrong.json" -o "$work/result"
expect_error "bad pattern" sim photo --scenario "$scenario" --board chessboard:9x6 --pose 0,0,0,0,0,400 -o "$work/result"
expect_error "unknown ArUco dictionary" sim photo --scenario "$scenario" --board charuco:5x7@20/14:DICT_9X9 --pose 0,0,0,0,0,400 -o "$work/result"
expect_error "--pose needs 6" sim photo --scenario "$scenario" --board chessboard:9x6@20 --pose 1,2,3 -o "$work/result"
expect_error "one of --print, --board and --sheet" sim photo --scenario "$scenario" -o "$work/result"
expect_error "one of --print, --board and --sheet" sim photo --scenario "$scenario" --board chessboard:9x6@20 --sheet 0,0,100,100,0 -o "$work/result"
expect_error "--sheet needs 5" sim photo --scenario "$scenario" --sheet 0,0,100 -o "$work/result"
expect_error "--sheet needs a width and a depth above 0" sim photo --scenario "$scenario" --sheet 0,0,0,100,0 -o "$work/result"
# The command line (CLI11, from each command's declared options): an unknown option is named
# before a missing one, a repeated one or a command without its verb is one line.
expect_error "^calbox: sim print: unknown option --frobnicate \\(see calbox sim print --help\\)$" sim print --frobnicate 3
expect_error "^calbox: sim print: unknown option --frob \\(see" sim print --scenario=x --frob=3
expect_error "^calbox: solve delta: -o: At Most 1 required but received 2" solve delta --machine a --measurements b -o "$work/x" -o "$work/y"
expect_error "^calbox: solve: needs a command: delta, galvo, planar \\(see calbox solve --help\\)$" solve
expect_error "^calbox: solve: unknown command 'fly' \\(delta, galvo, planar\\) \\(see calbox solve --help\\)$" solve fly
expect_error "^calbox: target delta: The following argument was not expected: stray" target delta --machine "$top/examples/delta.toml" -o "$work/result" stray
expect_error "is a file for --rrf alone" machine import --marlin "$work/ok.gcode" "$work/ok.gcode" -o "$work/result"
expect_error "^calbox: unknown command 'bogus' \\(see calbox --help\\)$" bogus
expect_error "unknown command 'fly'" fly

# camera and detect
printf 'not an image' > "$work/fake.png"
printf '%%YAML:1.0\n---\nmodel: [unclosed\n' > "$work/corrupt.yaml"
printf '%%YAML:1.0\n---\nmodel: pinhole\n' > "$work/incomplete.yaml"
"$calbox" sim photo --scenario "$scenario" --board chessboard:9x6@20 --on-bed -80,50,0 -o "$work/board.png" 2>/dev/null
expect_error "cannot read image .*missing.png: no such file" detect markers "$work/missing.png"
# OpenCV's sample photos (Debian's opencv-doc, in the manifest): one cut short in transfer is
# refused (libjpeg would fill it grey and calibrate from it), and photos of another board say
# how many held this one; nothing is written either way.
# A printer.cfg whose includes loop: one line naming the loop, no machine file.
printf '[include b.cfg]\n[printer]\nkinematics: delta\n' > "$work/a.cfg"
printf '[include a.cfg]\n' > "$work/b.cfg"
expect_error "includes loop: .*a.cfg -> .*b.cfg -> .*a.cfg" machine import --klipper "$work/a.cfg" -o "$work/result"
# A wildcard include ([include parts/*.cfg]) is every match, in Klipper's sorted order: the later
# part's delta_radius is the one in force.
mkdir -p "$work/klipper/parts"
printf '[include parts/*.cfg]\n[printer]\nkinematics: delta\nprint_radius: 90\n[stepper_a]\nposition_endstop: 300\narm_length: 215\n' > "$work/klipper/printer.cfg"
printf '[printer]\ndelta_radius: 99\n' > "$work/klipper/parts/a_frame.cfg"
printf '[printer]\ndelta_radius: 101.5\n' > "$work/klipper/parts/b_towers.cfg"
"$calbox" machine import --klipper "$work/klipper/printer.cfg" -o "$work/klipper/machine.toml" > /dev/null 2>&1 &&
    grep -qx 'radius_mm = 101.5' "$work/klipper/machine.toml" ||
    { echo "FAIL: a wildcard include was not read in sorted order"; failures=$((failures + 1)); }
printf 'echo:.Height:297.80    Ex:-0.14  Ey:-0.07  Ez:+0.00    Radius:100.79\n' > "$work/g33.log"
expect_error "G33's report leaves it out; give --diagonal-rod" machine import --marlin "$work/g33.log" -o "$work/result"
expect_error "takes one of --marlin, --rrf, --klipper" machine import -o "$work/result"
samples=/usr/share/doc/opencv-doc/examples/data
head -c 20000 "$samples/left01.jpg" > "$work/cut_short.jpg"
expect_error "cut_short.jpg: the JPEG is cut short" camera calibrate --pattern chessboard:9x6@25 \
    "$work/cut_short.jpg" "$samples/left02.jpg" "$samples/left03.jpg" "$samples/left04.jpg" -o "$work/result"
# The same cut-short photo handed to the appliance as its camera, and an empty file to detect: each
# named with what is wrong with it, not measured grey nor stopped on OpenCV's own assertion.
mkdir -p "$work/cut_photos" && cp "$work/cut_short.jpg" "$work/cut_photos/"
"$calbox" run --auto --scenario "$top/tests/scenarios/delta_cycle_small.toml" --data "$work/box_cut" \
    --camera-files "$work/cut_photos" > "$work/out" 2> "$work/err" < /dev/null
status=$?
if [ "$status" -ne 1 ] || ! grep -q "cut_short.jpg: the JPEG is cut short" "$work/err"; then
    echo "FAIL: a cut-short photo from --camera-files -> exit $status, stderr:"; sed 's/^/    /' "$work/err"
    failures=$((failures + 1))
fi
no_library_text "calbox run --camera-files (a cut-short photo)"
: > "$work/empty.png"
expect_error "cannot read image .*empty.png: the file is empty" detect markers "$work/empty.png"
expect_error "the board was found in 0 of 3 images" camera calibrate --pattern chessboard:10x7@30 \
    "$samples/left02.jpg" "$samples/left03.jpg" "$samples/left04.jpg" -o "$work/result"
expect_error "cannot read image .*fake.png: neither a PNG nor a JPEG" detect markers "$work/fake.png"
expect_error "unknown marker dictionary 'DICT_9X9_9'" detect markers "$work/board.png" --dict DICT_9X9_9
expect_error "no DICT_4X4_50 markers found" detect markers "$work/board.png"
expect_error "bad pattern 'chessboard:9by6@20'" detect chessboard "$work/board.png" --pattern chessboard:9by6@20
expect_error "no chessboard:7x4@20 found" detect chessboard "$work/board.png" --pattern chessboard:7x4@20
expect_error "corrupt YAML" camera plane --camera "$work/corrupt.yaml" --pattern chessboard:9x6@20 "$work/board.png" -o "$work/result"
expect_error "missing key 'image_width'" camera plane --camera "$work/incomplete.yaml" --pattern chessboard:9x6@20 "$work/board.png" -o "$work/result"
expect_error "cannot read camera file" camera plane --camera "$work/none.yaml" --pattern chessboard:9x6@20 "$work/board.png" -o "$work/result"
expect_error "found in 0 of 1 images \(0 corners\); a pinhole calibration needs at least 3 views and 60 corners" camera calibrate --pattern chessboard:7x4@20 "$work/board.png" -o "$work/result"
expect_error "--model must be pinhole or fisheye" camera calibrate --pattern chessboard:9x6@20 --model wide "$work/board.png" -o "$work/result"

# target svg
machine="$top/examples/delta.toml"
printf '<svg><rect width="1" height="1">\n</svg>' > "$work/malformed.svg"
printf '<svg><path d="M0 0 X 5 5"/></svg>' > "$work/command.svg"
printf '<svg xmlns="http://www.w3.org/2000/svg"></svg>' > "$work/empty.svg"
printf '<svg><rect width="abc" height="2"/></svg>' > "$work/numeric.svg"
printf '<svg xmlns="http://www.w3.org/2000/svg"><rect width="20" height="20"/></svg>' > "$work/square.svg"
printf '<svg><rect width="20" height="20"/></svg>' > "$work/no_namespace.svg"
head -c 11000000 /dev/zero | tr '\0' ' ' > "$work/huge.svg"
expect_error "malformed.svg: malformed XML at line 2" target svg "$work/malformed.svg" --machine "$machine" -o "$work/result"
expect_error "unknown command 'X'" target svg "$work/command.svg" --machine "$machine" -o "$work/result"
expect_error "nothing drawable" target svg "$work/empty.svg" --machine "$machine" -o "$work/result"
expect_error "no_namespace.svg: <svg> is not in SVG's namespace" target svg "$work/no_namespace.svg" --machine "$machine" -o "$work/result"
expect_error "non-numeric attribute width=\"abc\" on <rect>" target svg "$work/numeric.svg" --machine "$machine" -o "$work/result"
expect_error "over the limit of 10485760" target svg "$work/huge.svg" --machine "$machine" -o "$work/result"
expect_error "valid range 0.45 to 4.5 mm" target svg "$work/square.svg" --machine "$machine" --spacing 0.3 -o "$work/result"
# A drawing too large names the region it missed, its size, and the --fit that makes it fit
# (which then does).
expect_error "200.0 x 200.0 mm at scale [0-9.]+, does not fit the bed \\(a circle of [0-9.]+ mm radius\\); --fit [0-9.]+ \\(its larger side in mm\\) or less makes it fit" target svg "$work/square.svg" --machine "$machine" --fit 200 -o "$work/result"
largest=$(sed -n 's/.*--fit \([0-9.]*\) (its larger side.*/\1/p' "$work/err")
"$calbox" target svg "$work/square.svg" --machine "$machine" --fit "$largest" -o "$work/fits.gcode" > /dev/null 2>&1 ||
    { echo "FAIL: the suggested --fit $largest did not fit"; failures=$((failures + 1)); }
expect_error "does not fit the scanner's field \\(110.0 x 110.0 mm\\); --fit 109.9 " target svg "$work/square.svg" --machine "$top/examples/galvo_scanner.toml" --fit 200 -o "$work/result"
expect_error "cannot read drawing" target svg "$work/none.svg" --machine "$machine" -o "$work/result"
expect_error "fill-rule must be nonzero or evenodd" target svg "$work/square.svg" --machine "$machine" --fill-rule odd -o "$work/result"

# measure delta
"$calbox" sim camera --scenario "$scenario" -o "$work/camera.yaml"
"$calbox" camera plane --camera "$work/camera.yaml" --pattern chessboard:9x6@20 "$work/board.png" -o "$work/plane.yaml" > /dev/null
expect_error "photo 1 shows no DICT_4X4_50 markers" measure delta --camera "$work/camera.yaml" --plane "$work/plane.yaml" --machine "$machine" "$work/board.png" -o "$work/result"
expect_error "cannot read image .*fake.png: neither a PNG nor a JPEG" measure delta --camera "$work/camera.yaml" --plane "$work/plane.yaml" --machine "$machine" "$work/fake.png" -o "$work/result"
expect_error "cannot read plane file" measure delta --camera "$work/camera.yaml" --plane "$work/none.yaml" --machine "$machine" "$work/board.png" -o "$work/result"
expect_error "^calbox: measure delta: IMAGES is required \\(see calbox measure delta --help\\)$" measure delta --camera "$work/camera.yaml" --plane "$work/plane.yaml" --machine "$machine" -o "$work/result"

# measure delta on photos of the printed target that cannot be measured: issue 6's bad input.
cycle="$top/examples/delta_cycle.toml"
printer="$top/examples/delta_printer.toml"
"$calbox" target delta --machine "$printer" -o "$work/target.gcode" > /dev/null
"$calbox" sim print --scenario "$cycle" "$work/target.gcode" -o "$work/target_print.json" > /dev/null
"$calbox" sim camera --scenario "$cycle" -o "$work/cycle_camera.yaml"
"$calbox" sim photo --scenario "$cycle" --board chessboard:9x6@20 --on-bed -80,50,0 -o "$work/cycle_board.png"
"$calbox" camera plane --camera "$work/cycle_camera.yaml" --pattern chessboard:9x6@20 "$work/cycle_board.png" -o "$work/cycle_plane.yaml" > /dev/null
variant() {  # variant NAME SED-EXPRESSION: the cycle scenario with one thing changed
    sed "$2" "$cycle" > "$work/$1.toml"
}
variant overexposed 's/^vignetting = 0.15/vignetting = 0.15\nexposure_dn = 900.0/'
variant underexposed 's/^vignetting = 0.15/vignetting = 0.15\nexposure_dn = 40.0/'
variant aside 's/^look_at_mm = .*/look_at_mm = [-130.0, 0.0, 0.0]/'
for v in overexposed underexposed aside; do
    "$calbox" sim photo --scenario "$work/$v.toml" --print "$work/target_print.json" -o "$work/$v.png"
done
"$calbox" sim photo --scenario "$cycle" --board aruco:5x7@12/4:DICT_4X4_50 --on-bed -40,-60,0 -o "$work/other_target.png"
measure_photo() {  # measure_photo REGEX PHOTO
    expect_error "$1" measure delta --camera "$work/cycle_camera.yaml" --plane "$work/cycle_plane.yaml" \
        --machine "$printer" --bed-temperature 30 "$2" -o "$work/result"
}
measure_photo "photo 1 is over-exposed: [0-9]+ % of its bright part is clipped white" "$work/overexposed.png"
measure_photo "photo 1 is under-exposed: nothing in it is brighter than [0-9]+ of 255" "$work/underexposed.png"
measure_photo "photo 1 shows [0-9]+ of the target's 9 markers: .*the artifact is partly out of frame" "$work/aside.png"
measure_photo "photo 1 shows markers laid out unlike this machine's delta target .*another target" "$work/other_target.png"
measure_photo "photo 1 shows no DICT_4X4_50 markers" "$work/cycle_board.png"
expect_error "a photo bed temperature needs bed_material and bed_temperature_c" measure delta \
    --camera "$work/cycle_camera.yaml" --plane "$work/cycle_plane.yaml" --machine "$top/examples/delta.toml" \
    --bed-temperature 30 "$work/cycle_board.png" -o "$work/result"
expect_error "bed_material: 'wood' is not one of" target delta --machine <(sed 's/aluminium/wood/' "$printer") -o "$work/result"
# calbox run: devices and Modbus options checked before anything starts.
printf 'radius = 4\n' > "$work/badmap.toml"
expect_error "/nonexistent-photos: no photos" run --scenario "$top/tests/scenarios/delta_cycle_small.toml" --data "$work/box" --camera-files /nonexistent-photos
expect_error "not tcp:HOST:PORT or rtu:DEVICE:BAUD" run --scenario "$top/tests/scenarios/delta_cycle_small.toml" --data "$work/box" --modbus-server localhost
expect_error "--modbus-word-order: word order 'xyzw'" run --scenario "$top/tests/scenarios/delta_cycle_small.toml" --data "$work/box" --modbus-word-order xyzw
expect_error "--modbus-map needs --modbus-client" run --scenario "$top/tests/scenarios/delta_cycle_small.toml" --data "$work/box" --modbus-map "$work/badmap.toml"
expect_error "badmap.toml:1: 'radius' is not a result value" run --scenario "$top/tests/scenarios/delta_cycle_small.toml" --data "$work/box" --modbus-client tcp:127.0.0.1:1 --modbus-map "$work/badmap.toml"
printf '[modbus]\nsever = "tcp:h:1"\n' > "$work/typo.toml"
expect_error "typo.toml:2: \[modbus\] sever: unknown key" run --scenario "$top/tests/scenarios/delta_cycle_small.toml" --data "$work/box" --config "$work/typo.toml"
expect_error "/dev/null: not a serial device" run --scenario "$top/tests/scenarios/delta_cycle_small.toml" --data "$work/box" --console /dev/null
printf '[console]\nbaud = 115201\n' > "$work/baud.toml"
expect_error "baud.toml:2: \[console\] baud: '115201' is not one of 9600" run --scenario "$top/tests/scenarios/delta_cycle_small.toml" --data "$work/box" --config "$work/baud.toml"
expect_error "cannot open the serial device: No such file" run --scenario "$top/tests/scenarios/delta_cycle_small.toml" --data "$work/box" --modbus-server rtu:/dev/ttyNOPE9:19200

# The galvo mode: a photo that is not the grid, measurements and results of another machine,
# jobs compensate cannot carry through faithfully.
galvo="$top/examples/galvo_scanner.toml"
expect_error "the galvo target is for a galvo machine" target galvo --machine "$top/examples/delta.toml" -o "$work/result"
expect_error "the grid must have 7 to 101 circles a side, not 5" target galvo --machine "$galvo" --grid 5 -o "$work/result"
expect_error "\[galvo\] field_size_mm: must be between" target galvo --machine <(sed 's/field_size_mm = 110.0/field_size_mm = 1.0/' "$galvo") -o "$work/result"
expect_error "\[galvo\] on a delta machine" target delta --machine <(cat "$top/examples/delta.toml"; printf '[galvo]\nfield_size_mm = 50.0\n') -o "$work/result"
"$calbox" sim camera --scenario "$top/tests/scenarios/galvo_small.toml" -o "$work/galvo_camera.yaml"
"$calbox" sim photo --scenario "$top/tests/scenarios/galvo_small.toml" --board chessboard:15x11@8 --on-bed -56,40,0 -o "$work/galvo_board.png"
"$calbox" camera plane --camera "$work/galvo_camera.yaml" --pattern chessboard:15x11@8 "$work/galvo_board.png" -o "$work/galvo_plane.yaml" > /dev/null
expect_error "marks of the 31 x 31 grid's size in the photo .*not this target" measure galvo --camera "$work/galvo_camera.yaml" \
    --plane "$work/galvo_plane.yaml" --machine "$galvo" "$work/galvo_board.png" -o "$work/result"
expect_error "the photo is .*, the camera was calibrated at 2748x1836" measure galvo --camera "$work/galvo_camera.yaml" \
    --plane "$work/galvo_plane.yaml" --machine "$galvo" "$work/cycle_board.png" -o "$work/result"
expect_error "not a galvo measurements file" solve galvo --machine "$galvo" --measurements "$work/wrong.json" -o "$work/result"
printf '{"schema": "calbox.galvo-measurements/1", "machine_fingerprint": "fnv1a64:0", "target_fingerprint": "x", "photos": [], "grid_count": 31, "pitch_mm": 3.5, "symmetry": 0, "dark_marks": true, "nodes": [], "missing": [], "extra_mm": []}' > "$work/other_galvo.json"
expect_error "made for another machine file" solve galvo --machine "$galvo" --measurements "$work/other_galvo.json" -o "$work/result"
expect_error "wrong.json: not a planar or galvo result \(schema something else\)" compensate --result "$work/wrong.json" "$work/ok.gcode" -o "$work/result"
printf '{"schema": "calbox.galvo-result/1", "machine_fingerprint": "x", "pass": 1, "before": {"mean_mm": 0, "rms_mm": 0, "max_mm": 0, "points": 0}, "measurement_sigma_mm": 0, "predicted_rms_mm": 0, "table_interpolation_max_mm": 0, "table_interpolation_rms_mm": 0, "intended_mm": [], "landed_mm": [], "filled_nodes": [], "table": {"nodes": 2, "min_x_mm": -1, "min_y_mm": -1, "max_x_mm": 1, "max_y_mm": 1, "command_mm": [[-1,-1],[1,-1],[-1,1],[1,1]]}}' > "$work/identity_result.json"
printf 'G1 X0 Y0 F600\nG41 D1 X5 Y5\n' > "$work/cutter.gcode"
expect_error "cutter.gcode: line 2: cutter radius compensation \(G41\)" compensate --result "$work/identity_result.json" "$work/cutter.gcode" -o "$work/result"
# A line of 1 MB is no G-code: one line, nothing written.
{ printf 'G1 X0 Y0\n; '; head -c 1048576 /dev/zero | tr '\0' 'x'; printf '\n'; } > "$work/long_line.gcode"
expect_error "long_line.gcode: line 2 is 1048578 characters long" compensate --result "$work/identity_result.json" "$work/long_line.gcode" -o "$work/result"
expect_error "--segment must be 0.01 to 100 mm" compensate --result "$work/identity_result.json" "$work/ok.gcode" --segment 0 -o "$work/result"
expect_error "--tool-radius must be above 0 and at most 100 mm" compensate --result "$work/identity_result.json" "$work/ok.gcode" --tool-radius -1 -o "$work/result"

# The planar mode: the wrong machine, an area too small, a photo that is not the sheet,
# measurements of another machine.
router="$top/examples/router.toml"
expect_error "the planar target is for a router, cartesian printer or laser, not a delta" target planar --machine "$top/examples/delta.toml" -o "$work/result"
expect_error "at least 7 x 7 are needed" target planar --machine <(sed 's/bed_size_x_mm = 300.0/bed_size_x_mm = 120.0/' "$router") -o "$work/result"
expect_error "\[planar\] on a galvo machine" target galvo --machine <(cat "$galvo"; printf '[planar]\nhole_pitch_mm = 20.0\n') -o "$work/result"
expect_error "design: 3 holes; choose 8 to 141" target planar --machine "$router" --design 3 -o "$work/result"
# The hole count said is the job's: the command's line and the job's header give the grid's holes
# alike, and the job drills each of them and the backlash hole once.
said=$("$calbox" target planar --machine "$router" -o "$work/planar_target.gcode")
said_holes=$(sed -n 's/.* mm, \([0-9]*\) holes of .*and one more for the backlash$/\1/p' <<< "$said")
header_holes=$(sed -n '1s/.* mm, \([0-9]*\) holes of .*and one more for the backlash$/\1/p' "$work/planar_target.gcode")
plunges=$(grep -c '^G1 Z-' "$work/planar_target.gcode")
if [ -z "$said_holes" ] || [ "$said_holes" != "$header_holes" ] || [ "$plunges" -ne $((said_holes + 1)) ]; then
    echo "FAIL: target planar says '$said', its job's header '$(head -1 "$work/planar_target.gcode")', $plunges holes drilled"
    failures=$((failures + 1))
fi
"$calbox" sim camera --scenario "$top/tests/scenarios/planar_small.toml" -o "$work/planar_camera.yaml"
"$calbox" sim photo --scenario "$top/tests/scenarios/planar_small.toml" --board chessboard:15x11@15 --on-bed 45,235,0 -o "$work/planar_board.png"
"$calbox" camera plane --camera "$work/planar_camera.yaml" --pattern chessboard:15x11@15 "$work/planar_board.png" -o "$work/planar_plane.yaml" > /dev/null
expect_error "holes of the grid.s size in the first photo, the target has 143: not this target" measure planar --camera "$work/planar_camera.yaml" \
    --plane "$work/planar_plane.yaml" --machine "$router" "$work/planar_board.png" -o "$work/result"
expect_error "not a planar measurements file" solve planar --machine "$router" --measurements "$work/wrong.json" -o "$work/result"
printf '{"schema": "calbox.planar-measurements/1", "machine_fingerprint": "fnv1a64:0", "target_fingerprint": "x", "photos": [], "columns": 12, "rows": 12, "pitch_mm": 25, "mirrored": false, "holes": [], "backlash_hole": null, "missing": [], "extra_mm": []}' > "$work/other_planar.json"
expect_error "made for another machine file" solve planar --machine "$router" --measurements "$work/other_planar.json" -o "$work/result"
printf '{"schema": "calbox.planar-result/1", "machine_fingerprint": "x"}' > "$work/short_planar.json"
expect_error "short_planar.json: .*tool_length_mm" compensate --result "$work/short_planar.json" "$work/ok.gcode" -o "$work/result"

# The Raspberry Pi board on a machine without its devices: one line naming the first missing.
printf '[camera]\nv4l2_device = "/dev/calbox-test-no-camera"\n' > "$work/board.toml"
expect_error "^calbox: the camera: libcamera found no camera, and /dev/calbox-test-no-camera \(V4L2 camera\): open: No such file or directory$" \
    run --board rpi --board-file "$work/board.toml" --machine "$top/examples/delta_printer.toml" --data "$work/rpi"
printf '[camera]\nv4l2_device = "/dev/null"\n' > "$work/board_null.toml"
expect_error "^calbox: the camera: libcamera found no camera, and /dev/null: not a V4L2 device" \
    run --board rpi --board-file "$work/board_null.toml" --machine "$top/examples/delta_printer.toml" --data "$work/rpi"
printf '[lines]\nbuton = "GPIO17"\n' > "$work/board_typo.toml"
expect_error "board_typo.toml: \[lines\] buton: unknown key" \
    run --board rpi --board-file "$work/board_typo.toml" --machine "$top/examples/delta_printer.toml" --data "$work/rpi"
expect_error "needs --machine FILE" run --board rpi --board-file "$work/board.toml" --data "$work/rpi"
expect_error "unknown board 'pi': sim or rpi" run --board pi --data "$work/rpi"
expect_error "the sim board's" run --board rpi --auto --machine "$top/examples/delta_printer.toml" --data "$work/rpi"

[ "$failures" -eq 0 ] && echo "all $refusals error cases give one clear line, none a library's own text"
exit "$failures"
