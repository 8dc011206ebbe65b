#!/usr/bin/env bash
# calbox solve delta end to end: twin measurements -> fit -> lines the twin accepts; bad input
# gets one line, a non-zero exit and no result file.
set -euo pipefail
calbox="$1"; top="$2"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
"$calbox" sim measurements --scenario "$top/examples/delta_errors.toml" -o "$work/m.json" --probe "$work/probe.csv"
"$calbox" solve delta --machine "$top/examples/delta.toml" --measurements "$work/m.json" --probe "$work/probe.csv" -o "$work/result.json" | tee "$work/log"
grep -q '"calbox.delta-result/1"' "$work/result.json"
grep -q '"used_probe": true' "$work/result.json"
grep -q '"heights_from": "probe"' "$work/result.json"
# The same heights as a Marlin console log of G30 (the bed's height, so the gap negated) give
# the same fit.
/usr/bin/python3 - "$work/probe.csv" > "$work/g30.log" <<'PY'
import sys
for row in open(sys.argv[1]):
    if row[0] in "x#":
        continue
    x, y, z = (float(v) for v in row.split(","))
    print("Send: G30 X%.2f Y%.2f" % (x, y))
    print("Recv: Bed X: %.2f Y: %.2f Z: %.4f" % (x, y, -z))
    print("Recv: ok")
PY
"$calbox" solve delta --machine "$top/examples/delta.toml" --measurements "$work/m.json" --probe "$work/g30.log" -o "$work/from_log.json" > /dev/null
/usr/bin/python3 - "$work/result.json" "$work/from_log.json" <<'PY'
import json, sys
a, b = (json.load(open(f)) for f in sys.argv[1:])
for key in ("diagonal_rod_mm", "radius_mm", "height_mm"):
    assert abs(a["estimate"][key] - b["estimate"][key]) < 2e-4, (key, a["estimate"], b["estimate"])
PY
# The fit finds the hidden rod (251.1 mm, trims 0.6 -0.4 -0.3 -> in gauge 251.067).
/usr/bin/python3 - "$work/result.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
est = r["estimate"]["diagonal_rod_mm"]
assert abs(est - (251.1 + (0.6 - 0.4 - 0.3) / 3)) < 0.05, est
assert r["predicted_residual_mm"]["xy_rms"] < 0.01, r["predicted_residual_mm"]
assert r["commands"][0].startswith("M665 L") and r["commands"][-1] == "M500", r["commands"]
assert "height_mm" not in r["observability"]["held"], r["observability"]
PY
# The lines go to the twin as they are: M503 then reports them.
{ sed -n 's/^  \(M66[56].*\)$/\1/p' "$work/log"; echo "M500"; echo "G28"; echo "M503"; } > "$work/apply.gcode"
"$calbox" sim print --scenario "$top/examples/delta_errors.toml" "$work/apply.gcode" -o "$work/applied.json" > "$work/applied.log"
grep -q "echo:  $(sed -n 's/^  \(M665.*\)$/\1/p' "$work/log" | cut -d' ' -f1-3)" "$work/applied.log"
# Without heights the height is held, and the classic method runs beside.
"$calbox" solve delta --machine "$top/examples/delta.toml" --measurements "$work/m.json" -o "$work/noprobe.json" > /dev/null
grep -A3 '"held"' "$work/noprobe.json" | grep -q height_mm
"$calbox" solve delta --machine "$top/examples/delta.toml" --measurements "$work/m.json" --method classic --firmware klipper -o "$work/classic.json" > /dev/null
grep -q '"arm_length: ' "$work/classic.json"

failures=0
expect_error() {  # expect_error REGEX MEASUREMENTS [MACHINE]
    local regex="$1" m="$2" machine="${3:-$top/examples/delta.toml}"
    if "$calbox" solve delta --machine "$machine" --measurements "$m" -o "$work/bad_result.json" > /dev/null 2> "$work/err"; then
        echo "FAIL: accepted $m"; failures=$((failures + 1))
    elif [ "$(wc -l < "$work/err")" -ne 1 ] || ! grep -qE -- "$regex" "$work/err"; then
        echo "FAIL: $m:"; cat "$work/err"; failures=$((failures + 1))
    fi
    if [ -e "$work/bad_result.json" ]; then echo "FAIL: $m left a result"; failures=$((failures + 1)); fi
}
edit() {  # edit OUT PYTHON-STATEMENT (on dict d)
    /usr/bin/python3 -c "import json,sys; d=json.load(open('$work/m.json')); $2; json.dump(d, open('$1','w'))"
}
edit "$work/few.json" "d['features']=d['features'][:5]"
edit "$work/nan.json" "d['features'][3]['measured_mm'][0]=None"
edit "$work/off.json" "d['features'][4]['commanded_mm'][0]=120.0"
edit "$work/big.json" "[f.__setitem__('measured_mm',[v*1.05 for v in f['measured_mm']]) for f in d['features']]"
sed 's/^diagonal_rod_mm = 250.0/diagonal_rod_mm = 251.0/' "$top/examples/delta.toml" > "$work/other.toml"
expect_error "too few features: 5" "$work/few.json"
expect_error "feature f3 has a missing or non-finite" "$work/nan.json"
expect_error "feature f4 was commanded off the bed" "$work/off.json"
expect_error "refused: the measurements do not fit a delta" "$work/big.json"
expect_error "made for another machine" "$work/m.json" "$work/other.toml"
expect_error "malformed measurements" "$work/probe.csv"
printf 'x,y,z\n1,2,0.05\n1;2;3\n' > "$work/bad_probe.csv"
if "$calbox" solve delta --machine "$top/examples/delta.toml" --measurements "$work/m.json" --probe "$work/bad_probe.csv" -o "$work/bad_result.json" > /dev/null 2> "$work/err" ||
    ! grep -q "bad_probe.csv:3: expected x,y,z" "$work/err" || [ -e "$work/bad_result.json" ]; then
    echo "FAIL: a bad probe row:"; cat "$work/err"; failures=$((failures + 1))
fi
[ "$failures" -eq 0 ] && echo "solve delta works end to end and refuses bad input"
exit "$failures"
