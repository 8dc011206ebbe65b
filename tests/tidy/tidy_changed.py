#!/usr/bin/python3
"""The repo's .clang-tidy over the C++ files a change touches: clean, but for the functions
tests/tidy/known_findings.txt lists as over the size and complexity limits when they were set
(none of them may grow more complex; a function not listed may not pass a limit).

usage: tidy_changed.py SOURCE_DIR BUILD_DIR [BASE]
The change is the working tree against BASE (default: the commit before HEAD, or
$CALBOX_TIDY_BASE): a clean checkout checks its last commit's files. Only files the build
compiles are checked (BUILD_DIR's compile_commands.json); others are named as not checked.
First, tests/tidy/fixture_over_limits.cpp must be reported over both limits: the configuration
is in force and its findings are read. Exit 77 (skipped) without clang-tidy or git history."""
import concurrent.futures
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import time

FINDING = re.compile(r"^(?P<path>[^:\s][^:]*):(?P<line>\d+):(?P<col>\d+): (?P<kind>warning|error): "
                     r"(?P<message>.*) \[(?P<check>[^\]]+)\]$")
# A lambda is named "(lambda)" in tests/tidy/known_findings.txt.
SIZE = re.compile(r"(?:function '(?P<function>[^']+)'|(?P<lambda>lambda)) (?:has cognitive "
                  r"complexity of (?P<complexity>\d+)|exceeds recommended size/complexity "
                  r"thresholds)")
LAYERS = ("core/", "hal/", "drivers/", "board/", "firmware/")


def known_findings(path):
    """{(path, function, what): figure}: figure the complexity (int), or None for size."""
    known = {}
    for line in open(path):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        key = (parts[0], parts[1], parts[2])
        # Functions of one name in a file (albedo, one per scene) share the largest figure.
        figure = int(parts[3]) if parts[2] == "complexity" else None
        known[key] = figure if figure is None else max(figure, known.get(key) or 0)
    return known


def findings(source, args, directory=None):
    """clang-tidy's findings on one file: (relative path, line, check, message)."""
    run = subprocess.run(["clang-tidy", "--quiet"] + args, cwd=directory or source,
                         capture_output=True,
                         text=True, stdin=subprocess.DEVNULL)
    out = []
    for line in (run.stdout + run.stderr).splitlines():
        m = FINDING.match(line)
        if m:
            path = os.path.relpath(os.path.realpath(m["path"]), source)
            out.append((path, int(m["line"]), m["check"], m["message"]))
    return out


def judge(found, known):
    """The findings the change may not have: each as one line naming file, line and figure."""
    refused = []
    for path, line, check, message in found:
        where = "%s:%d" % (path, line)
        size = SIZE.match(message) if check.startswith("readability-function-") else None
        if size is None:
            refused.append("%s: %s [%s]" % (where, message, check))
            continue
        what = "complexity" if size["complexity"] else "lines"
        function = size["function"] or "(lambda)"
        key = (path, function, what)
        if key not in known:
            refused.append("%s: %s [%s]: not in tests/tidy/known_findings.txt (split it)"
                           % (where, message, check))
        elif what == "complexity" and int(size["complexity"]) > known[key]:
            refused.append("%s: '%s' grew to cognitive complexity %s from the %d listed"
                           % (where, function, size["complexity"], known[key]))
    return refused


def compile_flags(source, build):
    """{path in the source tree: (directory, the compiler's flags)} for every source the build
    compiles; a unity build's chunk gives its flags to each file it includes."""
    flags = {}
    for entry in json.load(open(os.path.join(build, "compile_commands.json"))):
        path = os.path.realpath(os.path.join(entry["directory"], entry["file"]))
        words = entry.get("arguments") or shlex.split(entry["command"])
        kept, skip = [], False
        for word in words[1:]:  # the compiler itself left out
            if skip:
                skip = False
            elif word in ("-o", "-MT", "-MF", "-c"):
                skip = True
            elif word not in ("-MD", path, entry["file"]):
                kept.append(word)
        names = [path]
        if "/Unity/unity_" in path:
            names = re.findall(r'^#include "([^"]+)"', open(path).read(), re.M)
        for name in names:
            flags[os.path.relpath(os.path.realpath(name), source)] = (entry["directory"], kept)
    return flags


def changed_files(source, base):
    names = subprocess.run(["git", "-C", source, "diff", "--name-only", "--diff-filter=AMR", base],
                           capture_output=True, text=True, check=True).stdout.split()
    return sorted(n for n in names if n.endswith(".cpp") and n.startswith(LAYERS))


def main():
    if len(sys.argv) not in (3, 4):
        print(__doc__, file=sys.stderr)
        return 2
    source, build = os.path.realpath(sys.argv[1]), os.path.realpath(sys.argv[2])
    base = sys.argv[3] if len(sys.argv) == 4 else os.environ.get("CALBOX_TIDY_BASE", "HEAD~1")
    if shutil.which("clang-tidy") is None:
        print("skipped: clang-tidy is not installed")
        return 77
    if subprocess.run(["git", "-C", source, "rev-parse", "--verify", "--quiet", base + "^{commit}"],
                      capture_output=True).returncode != 0:
        print("skipped: no commit %s in %s (a shallow clone?): nothing to compare with" % (base, source))
        return 77
    known = known_findings(os.path.join(source, "tests/tidy/known_findings.txt"))

    # The limits in force, and their findings read: the fixture is over both.
    fixture = "tests/tidy/fixture_over_limits.cpp"
    checks = {check for _, _, check, _ in findings(source, [fixture, "--", "-std=c++20"])}
    wanted = {"readability-function-size", "readability-function-cognitive-complexity"}
    if not wanted <= checks:
        print("FAIL: %s was not reported over %s: is .clang-tidy's configuration read?"
              % (fixture, ", ".join(sorted(wanted - checks))))
        return 1

    flags = compile_flags(source, build)
    files = changed_files(source, base)
    not_built = [f for f in files if f not in flags]
    files = [f for f in files if f in flags]
    for f in not_built:
        print("not checked (not compiled by this build): %s" % f)
    print("checking %d file(s) changed since %s" % (len(files), base), flush=True)
    refused = []
    started = time.time()
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        def tidy(f):
            directory, words = flags[f]
            return findings(source, [os.path.join(source, f), "--"] + words, directory)

        for f, found in zip(files, pool.map(tidy, files)):
            mine = judge(found, known)
            print("%s: %s" % (f, "clean" if not mine else "%d finding(s)" % len(mine)), flush=True)
            refused += mine
    print("%d file(s) in %.0f s" % (len(files), time.time() - started))
    for line in refused:
        print("FAIL: " + line)
    return 1 if refused else 0


if __name__ == "__main__":
    sys.exit(main())
