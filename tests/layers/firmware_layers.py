#!/usr/bin/python3
"""The firmware's house, from its own includes: firmware/ in folders by concern, each including
only its own folder and the folders below it (never one above: no cycle), and firmware reaching
drivers/ only through the files listed below, which hal/ is to replace one by one (a new file
that includes drivers/ fails here). Usage: firmware_layers.py SOURCE_DIR"""
import os
import re
import sys

top = sys.argv[1]
firmware = os.path.join(top, "firmware")
# Lowest first: a folder may include its own and those before it.
RANKS = ["loop", "links", "cycle", "modes", "plc", "console", "net", "cli", "app"]
# Folders of one rank side by side, neither including the other.
SAME_RANK = {"plc": 4, "console": 4}
# What still includes drivers/ (issue: the layers enforced). Nothing may join this list.
DRIVERS_ALLOWED = {
    "console/box_config.cpp", "console/console.cpp", "console/link_key.cpp",
    "console/link_key.hpp", "links/duet_link.hpp", "links/host_link.hpp",
    "links/moonraker_link.hpp", "links/octoprint_link.hpp", "net/box_network.cpp",
    "net/mqtt_report.cpp", "net/mqtt_report.hpp", "net/web_window.cpp", "net/web_window.hpp",
}


def rank(folder):
    if folder in SAME_RANK:
        return SAME_RANK[folder]
    return RANKS.index(folder) if RANKS.index(folder) < 4 else RANKS.index(folder) - 1


include = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
problems = []
files = 0
for folder, _, names in os.walk(firmware):
    for name in names:
        if not name.endswith((".cpp", ".hpp", ".inc")):
            continue
        path = os.path.join(folder, name)
        here = os.path.relpath(path, firmware)
        files += 1
        if os.sep not in here:
            problems.append(f"firmware/{here}: every file lives in a folder by concern")
            continue
        own = here.split(os.sep)[0]
        if own not in RANKS:
            problems.append(f"firmware/{here}: '{own}' is no folder of the house ({', '.join(RANKS)})")
            continue
        for target in include.findall(open(path, encoding="utf-8").read()):
            if target.startswith("drivers/") and here not in DRIVERS_ALLOWED:
                problems.append(f"firmware/{here} includes {target}: reach devices and the "
                                "network through hal/")
            if not target.startswith("firmware/"):
                continue
            parts = target.split("/")
            if len(parts) < 3:
                problems.append(f"firmware/{here} includes {target}: not in a folder")
                continue
            theirs = parts[1]
            if theirs not in RANKS:
                problems.append(f"firmware/{here} includes {target}: no such folder")
            elif theirs != own and rank(theirs) >= rank(own):
                problems.append(f"firmware/{here} ({own}) includes {target} ({theirs}): "
                                "a lower folder includes a higher one, or one of its rank")
stale = [f for f in DRIVERS_ALLOWED if not os.path.exists(os.path.join(firmware, f))]
for f in stale:
    problems.append(f"firmware/{f} is in DRIVERS_ALLOWED but not in the tree: take it out")
if files < 50:
    problems.append(f"only {files} firmware files found under {firmware}")
for p in problems:
    print("FAIL:", p)
print(f"{files} firmware files in {len(RANKS)} folders; {len(problems)} problems")
sys.exit(1 if problems else 0)
