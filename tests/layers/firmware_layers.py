#!/usr/bin/python3
"""The firmware's house, from its own includes and its build: firmware/ in folders by concern,
each including only its own folder and the folders below it (never one above: no cycle);
no firmware file including drivers/ (devices and the network are reached through hal/); the
boards opened only by the calbox binary's own folders (app/, cli/); and the firmware library
linking neither drivers nor boards. Usage: firmware_layers.py SOURCE_DIR"""
import os
import re
import sys

top = sys.argv[1]
firmware = os.path.join(top, "firmware")
# Lowest first: a folder may include its own and those of a lower rank. The PLC and the console
# side by side, neither including the other; the network and the service manager's watch too.
RANK = {"settings": 0, "loop": 1, "links": 2, "cycle": 3, "modes": 4, "plc": 5, "console": 5,
        "net": 6, "service": 6, "cli": 7, "app": 8}
RANKS = list(RANK)
# The calbox binary's own folders: the composition root and the subcommands, the only users of
# the boards (which bind drivers to hal/).
BOARD_USERS = {"app", "cli"}


def rank(folder):
    return RANK[folder]


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
            if target.startswith("drivers/"):
                problems.append(f"firmware/{here} includes {target}: reach devices and the "
                                "network through hal/")
            if target.startswith("board/") and own not in BOARD_USERS:
                problems.append(f"firmware/{here} includes {target}: only the composition root "
                                "(app/) and the subcommands (cli/) open boards")
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
# The build enforces it too: what the firmware library links.
cmake = open(os.path.join(top, "CMakeLists.txt"), encoding="utf-8").read()
links = re.search(r"target_link_libraries\(calbox_firmware\b([^)]*)\)", cmake)
if links is None:
    problems.append("CMakeLists.txt: no target_link_libraries(calbox_firmware ...)")
else:
    for library in ("calbox_drivers", "calbox_board", "calbox_sim", "calbox_rpi"):
        if re.search(r"\b" + library + r"\b", links.group(1)):
            problems.append(f"CMakeLists.txt: calbox_firmware links {library}: firmware reaches "
                            "devices through hal/ only")
if files < 50:
    problems.append(f"only {files} firmware files found under {firmware}")
for p in problems:
    print("FAIL:", p)
print(f"{files} firmware files in {len(RANKS)} folders; {len(problems)} problems")
sys.exit(1 if problems else 0)
