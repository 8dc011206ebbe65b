#!/usr/bin/env bash
# On demand, not under ctest: the appliance's wall time on the sim board, split into the twin's
# rendering (the camera), the machine link and the box's own work (measure, solve; button to
# corrections, machine time excluded), and the process's peak resident memory (the twin's
# included: its renderer runs in the same process). Each scenario runs twice: the first includes
# the one-time set-up; the second reuses it and is the figure to keep low (goal: under 1 s).
# Lines starting "ledger " are the figures toolchain/calbox.sh bench compares with
# tests/bench/ledger.json.
#   usage: tests/bench/bench_appliance.sh CALBOX_BINARY [SCENARIO...]
set -euo pipefail
calbox="${1:?usage: bench_appliance.sh CALBOX_BINARY [SCENARIO...]}"
shift
top="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
[ $# -gt 0 ] || set -- "$top/examples/delta_cycle.toml"
for scenario in "$@"; do
    name="$(basename "$scenario" .toml)"
    data="$(mktemp -d)"
    for run in setup cycle; do
        start=$(date +%s%N)
        /usr/bin/time -f "%M" -o "$data.rss" "$calbox" run --board sim --auto --scenario "$scenario" \
            --data "$data" < /dev/null 2> /dev/null | grep '^box:' > "$data.box"
        wall_ms=$(( ($(date +%s%N) - start) / 1000000 ))
        sed "s/^/$name ($run): /" "$data.box"
        box_s="$(sed -n 's/^box: \([0-9.]*\) s of its own work.*/\1/p' "$data.box")"
        peak_mb=$(( $(cat "$data.rss") / 1024 ))
        echo "$name ($run): wall $wall_ms ms, peak resident $peak_mb MB (the twin's included)"
        echo "ledger ${name}_${run}_box_s $box_s"
        echo "ledger ${name}_${run}_process_peak_mb $peak_mb"
    done
    rm -rf "$data" "$data.rss" "$data.box"
done
