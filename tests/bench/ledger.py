#!/usr/bin/python3
"""The speed ledger: the benchmarks' "ledger NAME VALUE" lines beside tests/bench/ledger.json.

usage: ledger.py LEDGER_JSON [--write] < bench output
Prints each figure, the committed one and their ratio; a figure that grew by more than a fifth
is flagged (exit 1). --write records the figures as the new committed ones.
"""
import json
import sys

path = sys.argv[1]
now = {}
for line in sys.stdin:
    parts = line.split()
    if len(parts) == 3 and parts[0] == "ledger":
        now[parts[1]] = float(parts[2])
try:
    with open(path) as f:
        committed = json.load(f)
except FileNotFoundError:
    committed = {"figures": {}}
before = committed.get("figures", {})
grown = []
print("%-40s %12s %12s %8s" % ("figure", "now", "committed", "now/was"))
for name in sorted(now):
    was = before.get(name)
    ratio = now[name] / was if was else None
    flag = ""
    if ratio is not None and ratio > 1.2:
        flag = "  <- grew by more than a fifth"
        grown.append(name)
    print("%-40s %12.4f %12s %8s%s" % (name, now[name], "%.4f" % was if was is not None else "-",
                                        "%.2f" % ratio if ratio is not None else "-", flag))
for name in sorted(set(before) - set(now)):
    print("%-40s %12s %12.4f  (not measured this time)" % (name, "-", before[name]))
if "--write" in sys.argv:
    committed["figures"] = dict(sorted({**before, **now}.items()))
    with open(path, "w") as f:
        json.dump(committed, f, indent=1)
        f.write("\n")
    print("written: " + path)
if grown:
    print("grew by more than a fifth: " + ", ".join(grown))
    sys.exit(1)
