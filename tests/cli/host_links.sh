#!/usr/bin/env bash
# A Klipper delta behind its Moonraker host (examples/moonraker_delta.toml), as a user runs it:
# calbox run --auto meets the delta goal by the twin's judgement, the host holds the printer.cfg
# the box wrote (its SAVE_CONFIG block) and Klipper's settings in force were read back; calbox
# revert puts the old printer.cfg back through the host. Each host fault ends the cycle in error
# with one line naming it, and printer.cfg on the host is untouched or fully the backup. The API
# key is never in a log, a record or the output. SIGTERM and SIGINT stop `calbox run` with status
# 0, the link closed (a print running on the host left to it, said in the log).
set -euo pipefail
calbox="$1"; top="$2"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
scenario="$top/examples/moonraker_delta.toml"
fail() { echo "FAIL: $*"; for f in "$work"/*.out "$work"/*.err; do echo "== $f"; tail -n 20 "$f"; done; exit 1; }

"$calbox" run --board sim --auto --scenario "$scenario" --data "$work/box" \
    > "$work/run.out" 2> "$work/run.err" < /dev/null || fail "calbox run --auto exited $?"
after=$(sed -nE 's/^after: XY rms ([0-9.]+) mm, max ([0-9.]+) mm$/\1 \2/p' "$work/run.out")
[ -n "$after" ] || fail "no after line"
awk -v a="$after" 'BEGIN { split(a, v, " "); exit !(v[1] <= 0.002 && v[2] <= 0.008) }' ||
    fail "after $after misses 0.002 / 0.008"
grep -q "cycle 1: the printer's settings in force: \[printer\] delta_radius: 140.000" "$work/run.err" ||
    fail "the settings in force were not read through the host"
grep -q 'writing printer.cfg.s SAVE_CONFIG block and restarting Klipper' "$work/run.err" ||
    fail "nothing was written through the host"
host_cfg="$work/box/twin-host/printer.cfg"
original="$work/box/cycle-0001-backup-printer.cfg"
# Its bed zeroed at the centre only, the printer takes two passes (as over serial,
# tests/cli/appliance.sh): the host holds the second's printer.cfg, each pass's old one its backup.
cmp -s "$host_cfg" "$work/box/cycle-0001-pass-2-printer.cfg" ||
    fail "the host does not hold the printer.cfg the box wrote last"
cmp -s "$work/box/cycle-0001-printer.cfg" "$work/box/cycle-0001-pass-2-backup-printer.cfg" ||
    fail "pass 2 did not back up the printer.cfg pass 1 wrote"
grep -q '^#\*# \[stepper_a\]$' "$host_cfg" || fail "no SAVE_CONFIG block on the host"
# The pass after the last correction measured the printer as Klipper took it: it holds.
grep -qE 'cycle 1: pass 3: .*nothing sent: the printer holds$' "$work/run.err" ||
    fail "the corrected printer did not hold"

"$calbox" revert --scenario "$scenario" --data "$work/box" \
    > "$work/revert.out" 2> "$work/revert.err" < /dev/null || fail "calbox revert exited $?"
grep -q '^reverted: the printer reports the settings saved before cycle 1$' "$work/revert.out" ||
    fail "revert did not report"
cmp -s "$host_cfg" "$original" || fail "the host's printer.cfg is not the backup after revert"

key=$(cat "$work/box/twin-host.key")
[ ${#key} -eq 32 ] || fail "the twin host's key is not 32 characters"

# Each fault on a box already set up (its camera, bed plane and reference marks), with a fresh
# host whose printer.cfg is the original one.
expect_fault() {  # name, expected text, what printer.cfg must be after, [faults] line, sed
    local name="$1" text="$2" cfg="$3" fault="$4" edit="${5:-}"
    local d="$work/$name"
    mkdir -p "$d/box"
    cp "$work/box/camera.yaml" "$work/box/plane.yaml" "$work/box/reference.yaml" "$d/box/"
    { if [ -n "$edit" ]; then sed -e "$edit" "$scenario"; else cat "$scenario"; fi
      printf '\n[faults]\n%s\n' "$fault"; } > "$d/scenario.toml"
    if "$calbox" run --board sim --auto --scenario "$d/scenario.toml" --data "$d/box" \
        > "$work/$name.out" 2> "$work/$name.err" < /dev/null; then
        fail "$name: the cycle completed"
    fi
    local last
    last=$(tail -n 1 "$work/$name.err")
    case "$last" in
        "calbox: the cycle did not complete: "*"$text"*) ;;
        *) fail "$name: the last line is '$last', not one naming '$text'" ;;
    esac
    local held="$d/box/twin-host/printer.cfg"
    case "$cfg" in
        original) cmp -s "$held" "$original" || fail "$name: printer.cfg on the host changed" ;;
        edited) { cat "$original"; printf '\n# max_z_velocity raised by hand\n'; } | cmp -s - "$held" ||
                    fail "$name: the hand edit on the host was not left as it was" ;;
    esac
    local k
    k=$(cat "$d/box/twin-host.key")
    if grep -rqF "$k" "$d/box" "$work/$name.out" "$work/$name.err" --exclude=twin-host.key; then
        fail "$name: the API key is in a log or a record"
    fi
    echo "host fault $name: $last"
}
expect_fault wrong_key "machine: Moonraker: http://127.0.0.1:" original 'host_wrong_key = true'
grep -q "HTTP 401" "$work/wrong_key.err" || fail "wrong_key: no HTTP 401"
expect_fault not_ready "Klipper is not ready (startup: mcu 'mcu': Unable to connect)" original \
    'host_printer_not_ready = true'
expect_fault restart "Moonraker: " original 'host_restart_at_request = 5'
expect_fault cancelled "machine: the print was cancelled on the host" original \
    'host_print_cancelled = true'
expect_fault silent "machine: Moonraker: no reply to" original 'host_silent_at_request = 5' \
    's/^reply_timeout_s = 30.0$/reply_timeout_s = 1.0/'
expect_fault upload_refused \
    "the host refused the upload of printer.cfg (HTTP 400: Insufficient disk space) (printer.cfg was not changed)" \
    original 'host_upload_refused = true'
expect_fault edited \
    "printer.cfg was changed on the host since the box read it; nothing was written (printer.cfg on the host is someone else's now: left as it is)" \
    edited 'host_config_edited = true'
expect_fault rejected \
    "Klipper did not start with the new printer.cfg (error: Option 'position_endstop' in section 'stepper_a' must be below 400) (the previous printer.cfg was restored)" \
    original 'host_new_config_rejected = true'

# The key is in no log, record or output of the whole run either.
if grep -rqF "$key" "$work/box" "$work/run.out" "$work/run.err" "$work/revert.out" \
    "$work/revert.err" --exclude=twin-host.key; then
    fail "the API key is in a log or a record"
fi

# SIGTERM while the host prints the box's target: status 0, the print left to the host.
mkdir -p "$work/stop/box"
cp "$work/box/camera.yaml" "$work/box/plane.yaml" "$work/box/reference.yaml" "$work/stop/box/"
sed -e 's/^segment_mm = 0.5$/segment_mm = 0.5\nhost_print_seconds = 60/' "$scenario" \
    > "$work/stop/scenario.toml"
"$calbox" run --board sim --auto --scenario "$work/stop/scenario.toml" --data "$work/stop/box" \
    > "$work/stop.out" 2> "$work/stop.err" < /dev/null &
pid=$!
for _ in $(seq 1 300); do
    grep -q 'make-target -> wait-machine' "$work/stop.err" && break
    sleep 0.1
done
grep -q 'make-target -> wait-machine' "$work/stop.err" || { kill -9 $pid; fail "the print never started"; }
sleep 0.5
kill -TERM $pid
status=0
wait $pid || status=$?
[ $status -eq 0 ] || fail "SIGTERM mid-print: exit $status"
grep -qE "^calbox: stopped by signal 15; the job in flight on moonraker http://127.0.0.1:[0-9]+ is left to the host \(cancel it there\)$" \
    "$work/stop.err" || fail "SIGTERM mid-print: the log does not say the print is left to the host"

# SIGINT on a serial printer's box waiting for its button: status 0, the link closed.
"$calbox" run --board sim --scenario "$top/tests/scenarios/delta_cycle_small.toml" \
    --data "$work/serial" > "$work/serial.out" 2> "$work/serial.err" < /dev/null &
pid=$!
for _ in $(seq 1 100); do
    grep -q 'waiting for the button' "$work/serial.err" && break
    sleep 0.1
done
kill -INT $pid
status=0
wait $pid || status=$?
[ $status -eq 0 ] || fail "SIGINT: exit $status"
grep -qx 'calbox: stopped by signal 2; the machine link is closed' "$work/serial.err" ||
    fail "SIGINT: the log does not say the link is closed"
echo "moonraker delta: after $after; revert restored printer.cfg; 8 host faults named; SIGTERM and SIGINT exit 0"
