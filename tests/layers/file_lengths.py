#!/usr/bin/python3
"""No source file over 700 lines (docs/architecture.md, Limits the build keeps): the C++, Python
and shell sources of every layer, the tests and the toolchain. A file past it is named with its
length; split it by what its parts are about. Usage: file_lengths.py SOURCE_DIR"""
import os
import sys

LIMIT = 700
FOLDERS = ("core", "hal", "drivers", "board", "firmware", "tests", "toolchain")
SOURCES = (".cpp", ".hpp", ".h", ".py", ".sh")

top = sys.argv[1]
read, over = 0, []
for folder in FOLDERS:
    for root, dirs, files in os.walk(os.path.join(top, folder)):
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and d != "corpus")
        for name in sorted(files):
            if not name.endswith(SOURCES):
                continue
            path = os.path.join(root, name)
            with open(path, encoding="utf-8", errors="replace") as f:
                lines = sum(1 for _ in f)
            read += 1
            if lines > LIMIT:
                over.append("%s: %d lines (the limit is %d)" % (os.path.relpath(path, top), lines,
                                                               LIMIT))
if read < 100:
    print("FAIL: only %d source files under %s: is it the source tree?" % (read, top))
    sys.exit(1)
for line in over:
    print("FAIL: " + line)
print("%d source files read, %d over %d lines" % (read, len(over), LIMIT))
sys.exit(1 if over else 0)
