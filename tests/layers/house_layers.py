#!/usr/bin/python3
"""The house's lower layers, from their includes and their build (firmware/ has its own test,
firmware_layers.py). core/ is computation: it includes only core/, and no header or call that
reaches a device, a file, the network or the clock. hal/ is interfaces: its headers include hal/
and the network's text formats in core/net/ (the one dependency on core/, drawn in
docs/architecture.md), no device library, and it builds one source, the completion primitive
every layer shares. drivers/ bind hal/ with core/'s help; board/ binds drivers to hal/, each
board folder seeing only itself and the devices type. core/'s own folders stand in an order
(CORE_ORDER), each seeing only those below it. Every library links only the layers below it. Usage: house_layers.py SOURCE_DIR"""
import os
import re
import sys

top = sys.argv[1]

# What core/ may not include: the clock, threads, files, the system's calls and devices.
CORE_FORBIDDEN_HEADERS = re.compile(
    r"^(chrono|thread|future|fstream|iostream|filesystem|ctime|time\.h|unistd\.h|fcntl\.h|"
    r"poll\.h|termios\.h|dirent\.h|sys/.*|linux/.*|netinet/.*|netdb\.h|"
    r"gpiod\.h|modbus/.*|modbus\.h|mosquitto\.h|systemd/.*|libcamera/.*|boost/.*)$")
# ... and what it may not call (a string of code, comments and strings taken out).
CORE_FORBIDDEN_CALLS = re.compile(
    r"std::(ifstream|ofstream|fstream|cout|cerr|clog|filesystem|system|getenv|time)\b|"
    r"\b(fopen|freopen|popen|getenv|printf|fprintf|puts|fputs|socket|sleep|usleep)\s*\(|"
    r"::(open|read|write|close)\s*\(|_clock::now\s*\(")
# The one exception, and why: a drawing's text is painted in the fonts it names, as a browser
# paints it, and fontconfig finds them (calbox_drawing is a library of its own, linked only by
# what reads drawings).
CORE_EXCEPTIONS = {("core/drawings/drawing.cpp", "fontconfig/fontconfig.h")}

# The device libraries hal/'s interfaces hide.
HAL_FORBIDDEN_HEADERS = re.compile(
    r"^(gpiod\.h|modbus/.*|modbus\.h|mosquitto\.h|systemd/.*|libcamera/.*|boost/.*|"
    r"linux/.*|netinet/.*|termios\.h|opencv2/.*)$")
# hal/'s sources: the completion primitive (an eventfd notifier and a background job on it).
HAL_SOURCES = {"hal/notifier.cpp"}

# What each lower layer's quoted includes may name.
ALLOWED = {
    "core": ("core/",),
    "hal": ("hal/", "core/net/"),
    "drivers": ("drivers/", "hal/", "core/"),
    "board": ("board/", "drivers/", "hal/", "core/"),
}
# core/'s folders, from the bottom: each includes only the files at core/'s root, itself and the
# folders below it, so that no two folders lean on each other (a G-code line's words under the
# machine models that read firmware replies; the machine models under the fits and the jobs that
# use them; the targets, which make jobs, under the modes).
CORE_ORDER = ["geometry", "vision", "gcode", "drawings", "net", "models", "solve", "jobs",
              "targets", "modes"]

# What each library may link of calbox's own.
LINKS = {
    "calbox_hal": set(),
    "calbox_core": set(),
    "calbox_drawing": {"calbox_core"},
    "calbox_drivers": {"calbox_hal", "calbox_core"},
    "calbox_board": {"calbox_core", "calbox_hal", "calbox_drivers"},
    "calbox_sim": {"calbox_board", "calbox_core", "calbox_hal", "calbox_drivers"},
    "calbox_rpi": {"calbox_board", "calbox_core", "calbox_hal", "calbox_drivers"},
}

def core_folder(path):
    """The core/ folder a path is in, "" at core/'s root."""
    parts = path.split("/")
    return parts[1] if len(parts) > 2 else ""


def core_order_problems(here, targets):
    mine = core_folder(here)
    if mine not in CORE_ORDER and mine != "":
        return [f"{here}: core/{mine}/ is not in house_layers.py's CORE_ORDER (where it stands "
                "among core/'s folders)"]
    rank = CORE_ORDER.index(mine) if mine else -1
    found = []
    for target in targets:
        theirs = core_folder(target)
        if not target.startswith("core/") or theirs in ("", mine):
            continue
        if theirs not in CORE_ORDER or CORE_ORDER.index(theirs) > rank:
            found.append(f"{here} includes \"{target}\": core/{mine or '.'} sees only the "
                         "folders below it (" + (", ".join(CORE_ORDER[:max(rank, 0)]) or "none")
                         + ")")
    return found


quoted = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
angled = re.compile(r'^\s*#\s*include\s+<([^>]+)>', re.M)
comments_and_strings = re.compile(r'//[^\n]*|/\*.*?\*/|"(?:\\.|[^"\\])*"', re.S)
problems = []
files = 0

for layer in ALLOWED:
    for folder, _, names in os.walk(os.path.join(top, layer)):
        for name in sorted(names):
            if not name.endswith((".cpp", ".hpp", ".inc")):
                continue
            path = os.path.join(folder, name)
            here = os.path.relpath(path, top).replace(os.sep, "/")
            files += 1
            text = open(path, encoding="utf-8").read()
            for target in quoted.findall(text):
                if not target.startswith(ALLOWED[layer]):
                    problems.append(f"{here} includes \"{target}\": {layer}/ sees only "
                                    + ", ".join(ALLOWED[layer]))
                # A board folder sees itself and the devices type, no other board.
                parts = here.split("/")
                if layer == "board" and len(parts) > 2 and target.startswith("board/"):
                    theirs = target.split("/")
                    if len(theirs) > 2 and theirs[1] != parts[1]:
                        problems.append(f"{here} includes \"{target}\": one board does not open "
                                        "another's files")
            for header in angled.findall(text):
                if layer == "core" and CORE_FORBIDDEN_HEADERS.match(header) and \
                        (here, header) not in CORE_EXCEPTIONS:
                    problems.append(f"{here} includes <{header}>: core/ touches no device, "
                                    "file, network or clock")
                if layer == "hal" and HAL_FORBIDDEN_HEADERS.match(header):
                    problems.append(f"{here} includes <{header}>: hal/ is interfaces; the "
                                    "library belongs in drivers/")
            if layer == "core":
                problems.extend(core_order_problems(here, quoted.findall(text)))
                code = comments_and_strings.sub("", text)
                for call in CORE_FORBIDDEN_CALLS.finditer(code):
                    problems.append(f"{here}: '{call.group(0).strip()}': core/ touches no "
                                    "device, file, network or clock")
            if layer == "hal" and name.endswith(".cpp") and here not in HAL_SOURCES:
                problems.append(f"{here}: hal/ holds interfaces; an implementation belongs in "
                                "drivers/ (its one source is the completion primitive)")

# The build: each library's calbox libraries, from CMakeLists.txt's target_link_libraries.
cmake = open(os.path.join(top, "CMakeLists.txt"), encoding="utf-8").read()
cmake = re.sub(r"#[^\n]*", "", cmake)
seen = set()
for target, body in re.findall(r"target_link_libraries\(\s*(calbox_\w+)(.*?)\)", cmake, re.S):
    if target not in LINKS:
        continue
    seen.add(target)
    for lib in re.findall(r"\bcalbox_\w+", body):
        if lib not in LINKS[target]:
            allowed = ", ".join(sorted(LINKS[target]))
            problems.append(f"CMakeLists.txt: {target} links {lib}: "
                            + (f"it may link only {allowed}" if allowed
                               else "it links none of calbox's own libraries"))
for target in LINKS:
    if not re.search(r"add_library\(\s*%s\b" % target, cmake):
        problems.append(f"CMakeLists.txt: no library {target}: the house's layers are its "
                        "libraries")

if problems:
    print("\n".join(problems))
    sys.exit(1)
print(f"{files} files of core/, hal/, drivers/ and board/ and {len(seen)} libraries keep to "
      "their layers")
