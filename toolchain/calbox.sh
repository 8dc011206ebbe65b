#!/usr/bin/env bash
# calbox developer entry point: installs what is missing (Debian packages from
# toolchain/packages.txt), configures and builds with a CMake preset, then runs what was asked.
#
#   toolchain/calbox.sh run   [--preset P]   the main job: calbox run --board sim --auto (only the
#                                             calbox binary, and only the packages the box needs;
#                                             default preset: release, what the package ships)
#   toolchain/calbox.sh test  [--preset P]   every test under ctest (default preset: dev), after
#                                             building what ships too (the release preset's calbox)
#   toolchain/calbox.sh build [--preset P]   configure and build only
#   toolchain/calbox.sh bench [--write]      the benchmarks on the release preset, beside the
#                                             committed figures (tests/bench/ledger.json)
# Presets: dev, asan, release, fuzz, and arm64 (cross-built for the Raspberry Pi, run under qemu).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
top="$(dirname "$here")"

usage() { sed -n '2,13p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; }

action="${1:-}"
[ -n "$action" ] || { usage >&2; exit 2; }
shift
preset=""
write=""
while [ $# -gt 0 ]; do
    case "$1" in
        --preset) preset="${2:?--preset needs a name: dev, asan, release or arm64}"; shift 2 ;;
        --write) [ "$action" = bench ] || { echo "calbox.sh: --write is bench's" >&2; exit 2; }
                 write=--write; shift ;;
        -h|--help) usage; exit 0 ;;
        *) echo "calbox.sh: unknown argument '$1'" >&2; exit 2 ;;
    esac
done
case "$action" in
    run) preset="${preset:-release}" ;;
    test|build) preset="${preset:-dev}" ;;
    bench) [ -z "$preset" ] || [ "$preset" = release ] || {
               echo "calbox.sh: bench measures the release preset (what ships)" >&2; exit 2; }
           preset=release ;;
    -h|--help|help) usage; exit 0 ;;
    *) echo "calbox.sh: unknown action '$action' (run, test, build or bench)" >&2; exit 2 ;;
esac

# A manifest line is a package this machine needs for every preset, or one tagged for the arm64
# preset: `arm64-host` on this machine, `arm64-sysroot` unpacked by toolchain/arm64_sysroot.sh.
install_missing() {
    local missing=()
    while read -r first second; do
        case "$first" in ''|'#'*) continue ;; esac
        local pkg="$first"
        if [ -n "$second" ]; then
            case "$first" in
                arm64-host) [ "$preset" = arm64 ] || continue ;;
                test) [ "$action" != run ] || continue ;;
                *) continue ;;
            esac
            pkg="$second"
        fi
        if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q 'install ok installed'; then
            missing+=("$pkg")
        fi
    done < "$here/packages.txt"
    [ ${#missing[@]} -eq 0 ] && return 0
    if [ "$(id -u)" -ne 0 ]; then
        echo "calbox.sh: missing Debian packages (run as root to install): ${missing[*]}" >&2
        exit 1
    fi
    echo "calbox.sh: installing ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y --no-install-recommends "${missing[@]}"
}

build() {
    cd "$top"
    if [ "$preset" = arm64 ]; then
        bash "$here/arm64_sysroot.sh" "$top/build/arm64-sysroot"
    fi
    # Configured every time (quick when nothing changed): the tests appear once CppUTest is there.
    cmake --preset "$preset" > /dev/null
    if [ "$action" = run ]; then
        cmake --build "build/$preset" -j 2 --target calbox
    elif [ "$action" = bench ]; then
        cmake --build "build/$preset" -j 2 --target calbox bench_delta bench_galvo bench_planar
    else
        cmake --build "build/$preset" -j 2
    fi
}

# What ships, built beside the tests: the release preset's calbox. GCC warns at -O3 where the dev
# preset's -O1 does not (its false -Wrestrict once stopped the release build while the suite
# passed), so a test run that did not build it would not say that the package builds.
build_shipped() {
    [ "$action" = test ] && [ "$preset" = dev ] || return 0
    cd "$top"
    cmake --preset release > /dev/null
    cmake --build build/release -j 2 --target calbox
}

install_missing
build
build_shipped
case "$action" in
    build) ;;
    test)
        # Under qemu the long tests (whole twin cycles, 12 MP photos) would take hours: left out.
        # The slow label (thousands of mutated jobs through rs274) runs on demand: ctest -L slow.
        skip=(-LE slow)
        [ "$preset" != arm64 ] || skip=(-LE "long|slow")
        # Three at a time on two cores: a fifth of the suite's time is tests waiting (an idle
        # limit, a broker's back-off, a hung camera, Prometheus's scrapes), which a third job
        # fills; the build stays at -j2.
        cd "$top" && ctest --test-dir "build/$preset" --output-on-failure -j 3 "${skip[@]}" < /dev/null ;;
    bench)
        # One after the other, nothing else running: each prints its figures and "ledger" lines.
        cd "$top"
        out="$(mktemp)"
        trap 'rm -f "$out"' EXIT
        for b in bench_delta bench_planar bench_galvo; do
            "build/$preset/tests/bench/$b" | tee -a "$out"
        done
        bash tests/bench/bench_appliance.sh "build/$preset/calbox" examples/delta_cycle.toml \
            examples/planar_cycle.toml examples/galvo_cycle.toml | tee -a "$out"
        /usr/bin/python3 tests/bench/ledger.py tests/bench/ledger.json $write < "$out" ;;
    run)
        # The appliance on the digital twin, from an empty data directory so that the one-time
        # set-up (camera and bed plane from photos) runs too; then one whole cycle, judged.
        # Huge pages for the photos' large buffers (tests/CMakeLists.txt says why).
        export GLIBC_TUNABLES=glibc.malloc.hugetlb=1
        cd "$top" && rm -rf out/box && mkdir -p out
        binary="build/$preset/calbox"
        [ "$preset" != arm64 ] || binary="build/arm64/calbox-emulated"
        exec "$binary" run --board sim --auto --scenario examples/delta_cycle.toml --data out/box ;;
esac
