#!/usr/bin/python3
"""Each library's include directories are what its layer may see, and the compiler holds them:
with a library's own flags (from the build's compile_commands.json), a header of a layer it may
include preprocesses, and one of a layer it may not is a missing file. Every calbox library and
the calbox binary must have a rule here and no include directory into the source tree but its
view (cmake/layer_view.cmake). Usage: layer_views.py SOURCE_DIR BUILD_DIR"""
import json
import os
import re
import shlex
import subprocess
import sys
import tempfile

source, build = (os.path.realpath(p) for p in sys.argv[1:3])

# target: (headers it may include, headers it may not). One header per layer it must not see,
# and one beside it that it must, so that a refusal is the view's and not a broken probe.
RULES = {
    "calbox_core": (["core/models/machine_file.hpp", "core/net/endpoints.hpp"],
                    ["hal/clock.hpp", "drivers/file_storage.hpp", "board/devices.hpp",
                     "firmware/cli/version.hpp"]),
    "calbox_drawing": (["core/drawings/drawing.hpp"], ["hal/clock.hpp", "firmware/cli/version.hpp"]),
    "calbox_hal": (["hal/clock.hpp", "core/net/endpoints.hpp"],
                   ["core/models/machine_file.hpp", "drivers/file_storage.hpp",
                    "firmware/cli/version.hpp"]),
    "calbox_drivers": (["drivers/file_storage.hpp", "hal/clock.hpp", "core/models/machine_file.hpp"],
                       ["board/devices.hpp", "firmware/cli/version.hpp"]),
    "calbox_board": (["board/devices.hpp", "drivers/file_storage.hpp"],
                     ["board/sim/sim_board.hpp", "board/rpi/rpi_board.hpp",
                      "firmware/cli/version.hpp"]),
    "calbox_sim": (["board/sim/sim_board.hpp", "board/devices.hpp"],
                   ["board/rpi/rpi_board.hpp", "firmware/cli/version.hpp"]),
    "calbox_rpi": (["board/rpi/rpi_board.hpp", "board/devices.hpp"],
                   ["board/sim/sim_board.hpp", "firmware/cli/version.hpp"]),
    "calbox_version": (["firmware/cli/version.hpp"], ["firmware/cycle/cycle.hpp", "core/net/endpoints.hpp"]),
    "calbox_firmware": (["firmware/cycle/cycle.hpp", "hal/clock.hpp"],
                        ["drivers/file_storage.hpp", "board/devices.hpp"]),
    "calbox": (["firmware/app/box.hpp", "board/sim/sim_board.hpp"], ["tests/unit/appliance_rig.hpp"]),
}

commands = json.load(open(os.path.join(build, "compile_commands.json")))
target_of = re.compile(r"CMakeFiles/(calbox[a-z_]*)\.dir/")
first_command = {}
for entry in commands:
    args = shlex.split(entry["command"])
    output = args[args.index("-o") + 1] if "-o" in args else ""
    found = target_of.search(output)
    # The tests' own objects (calbox_test_main...) see the whole tree, as every test does.
    if found and not found.group(1).startswith("calbox_test") and found.group(1) not in first_command:
        first_command[found.group(1)] = (args, entry["directory"])

problems = []
for target in sorted(set(first_command) - set(RULES)):
    problems.append(f"{target}: no rule in layer_views.py (what its layer may see)")
for target in sorted(set(RULES) - set(first_command)):
    problems.append(f"{target}: not in {build}/compile_commands.json")


def include_dirs(args):
    dirs = []
    for i, arg in enumerate(args):
        if arg in ("-I", "-isystem", "-iquote") and i + 1 < len(args):
            dirs.append(args[i + 1])
        elif arg.startswith("-I") and len(arg) > 2:
            dirs.append(arg[2:])
    return dirs


def preprocess(args, directory, header, scratch):
    """The compiler's flags for one source, run on a file that includes only header."""
    probe = os.path.join(scratch, "probe.cpp")
    with open(probe, "w") as out:
        out.write(f'#include "{header}"\n')
    kept, skip = [], False
    for arg in args:
        if skip:
            skip = False
            continue
        if arg in ("-o", "-c", "-MT", "-MF"):
            skip = True
            continue
        if arg in ("-MD", "-MMD") or arg.startswith(("-fsanitize", "-fuse-ld")):
            continue
        kept.append(arg)
    run = subprocess.run(kept + ["-E", "-o", os.devnull, probe], cwd=directory,
                         capture_output=True, text=True)
    return run.returncode, run.stderr


for header in sorted({h for pair in RULES.values() for side in pair for h in side}):
    if not os.path.isfile(os.path.join(source, header)):
        problems.append(f"{header}: named in layer_views.py's RULES, not in the source tree")

checks = 0
with tempfile.TemporaryDirectory() as scratch:
    for target, (allowed, forbidden) in sorted(RULES.items()):
        if target not in first_command:
            continue
        args, directory = first_command[target]
        for d in include_dirs(args):
            real = os.path.realpath(os.path.join(directory, d))
            inside_source = real == source or real.startswith(source + os.sep)
            if inside_source and not real.startswith(build + os.sep):
                problems.append(f"{target}: includes {d}, a folder of the source tree (only its "
                                "layer view may be)")
        for header in allowed:
            code, err = preprocess(args, directory, header, scratch)
            checks += 1
            if code != 0:
                first = err.strip().splitlines()[0] if err.strip() else f"exit {code}"
                problems.append(f"{target}: may include {header}, but its flags refuse it: {first}")
        for header in forbidden:
            code, err = preprocess(args, directory, header, scratch)
            checks += 1
            if code == 0:
                problems.append(f"{target}: includes {header}, which its layer may not see")
            elif "No such file" not in err:
                first = err.strip().splitlines()[0] if err.strip() else f"exit {code}"
                problems.append(f"{target}: {header} refused, but not as a missing file: {first}")

for p in problems:
    print("FAIL:", p)
print(f"{len(first_command)} libraries, {checks} includes tried, {len(problems)} problem(s)")
sys.exit(1 if problems else 0)
