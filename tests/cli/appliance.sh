#!/usr/bin/env bash
# calbox run --auto and calbox revert as a user runs them, as two processes on one data
# directory: the cycle meets the goal by the twin's judgement, the twin printer stores the
# correction (its EEPROM lives in the data directory), revert puts back what was there and the
# printer reports it; revert with nothing to revert is one line and exit 1.
set -euo pipefail
calbox="$1"; top="$2"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
scenario="$top/tests/scenarios/delta_cycle_small.toml"
fail() { echo "FAIL: $*"; for f in "$work"/*.out "$work"/*.err; do echo "== $f"; tail -n 20 "$f"; done; exit 1; }

"$calbox" run --board sim --auto --scenario "$scenario" --data "$work/box" \
    > "$work/run.out" 2> "$work/run.err" < /dev/null || fail "calbox run --auto exited $?"
grep -qE '^before: XY rms 0\.25[0-9]+ mm' "$work/run.out" || fail "no before line"
after=$(sed -nE 's/^after: XY rms ([0-9.]+) mm, max ([0-9.]+) mm$/\1 \2/p' "$work/run.out")
[ -n "$after" ] || fail "no after line"
awk -v a="$after" 'BEGIN { split(a, v, " "); exit !(v[1] <= 0.002 && v[2] <= 0.005) }' ||
    fail "after $after misses 0.002 / 0.005"
# Its bed is zeroed at the centre only: the first pass levels it, the second measures the
# verification print laid on the levelled bed and sends what is left, the third finds it holds.
grep -qE 'cycle 1: pass 1: the nozzle.s gap varied by 0\.[3-9][0-9]* mm .*is the next pass$' "$work/run.err" ||
    fail "no first pass that asked for another"
grep -qE 'cycle 1: pass 2: the nozzle.s gap varied by 0\.0[0-9]* mm ' "$work/run.err" ||
    fail "no second pass on a level bed"
grep -qE 'cycle 1: pass 3: .*nothing sent: the printer holds$' "$work/run.err" ||
    fail "no third pass that found the printer holding"
grep -q 'cycle 1: idle -> setup-camera' "$work/run.err" || fail "the first run did not set up"
stored="$work/box/twin-printer-settings.gcode"
grep -q '^M665 L25[01]\.[0-9]* ' "$stored" || fail "the printer stored nothing"
grep -q '^M665 L250.000 R140.000 H300.107 X0.000' "$stored" && fail "the correction was not stored"

"$calbox" revert --scenario "$scenario" --data "$work/box" \
    > "$work/revert.out" 2> "$work/revert.err" < /dev/null || fail "calbox revert exited $?"
grep -q '^reverted: the printer reports the settings saved before cycle 1$' "$work/revert.out" ||
    fail "revert did not report"
grep -qx 'M665 L250.000 R140.000 H300.107 X0.000 Y0.000 Z0.000 A0.000 B0.000 C0.000' "$stored" ||
    fail "the printer does not hold the backed-up settings: $(cat "$stored")"

mkdir "$work/empty"
if "$calbox" revert --scenario "$scenario" --data "$work/empty" \
    > "$work/empty.out" 2> "$work/empty.err" < /dev/null; then fail "revert with no cycle exited 0"; fi
[ "$(wc -l < "$work/empty.err")" -eq 1 ] || fail "revert with no cycle: not one line"
grep -q 'revert: no cycle has run here' "$work/empty.err" || fail "revert with no cycle: wrong reason"
echo "appliance: run then revert: after $after mm; the printer holds the backup again"
