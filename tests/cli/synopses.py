#!/usr/bin/python3
"""Each command's synopsis in docs/ names exactly the options and arguments its --help lists.

The synopses are the code-block lines of docs/*.md that start with `calbox COMMAND` and show a
placeholder (a word in capitals: FILE, IMAGES, X,Y) or an optional part ([--preview PNG]), with
the indented lines that continue them; lines with neither are examples, not synopses. A synopsis
of `calbox detect chessboard|circles` stands for both. `calbox --help` and each group's --help give the
commands; every command must have a synopsis, and the options and positional arguments of its
synopses together must be those of its --help."""
import functools
import re
import subprocess
import sys
from pathlib import Path

calbox, top = sys.argv[1], Path(sys.argv[2])


@functools.lru_cache(maxsize=None)
def help_of(words):
    done = subprocess.run([calbox, *words, "--help"], capture_output=True, text=True,
                          stdin=subprocess.DEVNULL)
    if done.returncode != 0 or done.stderr:
        sys.exit(f"FAIL: calbox {' '.join(words)} --help exits {done.returncode}: {done.stderr}")
    return done.stdout


def listed(text, heading):
    """The first words of the lines under HEADING: in CLI11's help."""
    names, on = [], False
    for line in text.splitlines():
        if line.endswith(":") and not line.startswith(" "):
            on = line == heading + ":"
            continue
        if on and line.startswith("  ") and not line.startswith("   "):
            names.append(line.split()[0])
    return names


def commands():
    out = []
    for group in listed(help_of(()), "Subcommands"):
        verbs = listed(help_of((group,)), "Subcommands")
        out += [(group, v) for v in verbs] if verbs else [(group,)]
    return out


def declared(path):
    text = help_of(tuple(path))
    options = set()
    for first in listed(text, "Options"):
        options |= {n for n in first.split(",") if n.startswith("-")}
    options -= {"-h", "--help"}
    return options, set(listed(text, "Positionals"))


def synopses():
    found = {}
    for doc in sorted((top / "docs").glob("*.md")):
        in_block, current = False, None
        for line in doc.read_text().splitlines():
            if line.startswith("```"):
                in_block, current = not in_block, None
                continue
            if not in_block:
                continue
            if line.startswith("calbox "):
                current = [line]
                found.setdefault(doc.name, []).append(current)
            elif current is not None and re.match(r"^\s+[\[(\-A-Z]", line):
                current.append(line)
            else:
                current = None
    out = {}
    for doc, blocks in found.items():
        for block in blocks:
            text = " ".join(block).split("#")[0]
            if "[" not in text and not re.search(r"\b[A-Z][A-Z_.]+\b", text):
                continue  # an example
            words = text.split()
            for verb in words[2].split("|"):
                out.setdefault((words[1], verb), []).append((doc, text))
            out.setdefault((words[1],), []).append((doc, text))
    return out


failures = []
written = synopses()
for path in commands():
    options, positionals = declared(path)
    shown = written.get(path, [])
    name = "calbox " + " ".join(path)
    if not shown:
        failures.append(f"{name}: no synopsis in docs/")
        continue
    text = " ".join(t for _, t in shown)
    in_docs = set(re.findall(r"(?<![\w-])(--[a-z][a-z-]*|-[a-z])\b", text))
    for o in sorted(options - in_docs):
        failures.append(f"{name}: --help lists {o}, its synopsis ({shown[0][0]}) does not")
    for o in sorted(in_docs - options):
        failures.append(f"{name}: its synopsis ({shown[0][0]}) names {o}, --help does not")
    for p in sorted(positionals):
        if not re.search(r"(?<![\w-])" + re.escape(p) + r"(?![\w-])", text):
            failures.append(f"{name}: --help's argument {p} is not in its synopsis ({shown[0][0]})")

# Every picture the README and docs/ show is in the repository (the web page's screenshots once
# were not: .gitignore dropped them).
for page in [top / "README.md", *sorted((top / "docs").glob("*.md"))]:
    for target in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", page.read_text()):
        if not (page.parent / target).is_file():
            failures.append(f"{page.relative_to(top)} shows {target}, which is not in the repository")
        elif subprocess.run(["git", "-C", str(top), "ls-files", "--error-unmatch",
                             str((page.parent / target).relative_to(top))],
                            capture_output=True).returncode not in (0, 128):
            failures.append(f"{page.relative_to(top)} shows {target}, which git does not keep")

for f in failures:
    print("FAIL:", f)
print(f"{len(commands())} commands checked against their synopses, {len(failures)} differences")
sys.exit(1 if failures else 0)
