#!/usr/bin/env python3
"""Checks that no source, test, script, example or doc file refers to an issue
tracker or to the IDs of a review report that users do not have: the
repository must say what a thing is, not which ticket asked for it.

A tag is
  * the word "issue" or "issues" followed by a number ("issue N", "issue-N",
    "issue #N", "issues N and M");
  * '#' followed by a number of at most four digits, not after a letter,
    digit, '&' or '#' (so six-digit colours and "&#N;" entities pass);
  * a review-report ID: D or E and a one- or two-digit number, alone or in a
    comma list, followed by ':' and a space, or in parentheses.

Scans the text files under lib/, drivers/, tests/, docs/, scripts/, python/,
examples/, bench/, fuzz/ and cmake/, and README.md and CMakeLists.txt at
the root. Exit status 1 with one line per tag found."""
import os
import re
import sys

root = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
folders = ("lib", "drivers", "tests", "docs", "scripts", "python", "examples", "bench", "fuzz", "cmake")
report_id = r"[DE][1-9][0-9]?"
tag = re.compile(r"\b[Ii]ssues?[ -]?#?[0-9]+"
                 r"|(?<![\w&#])#[0-9]{1,4}\b(?![0-9A-Fa-f])"
                 rf"|\b{report_id}(?:, ?{report_id})*:(?=\s)"
                 rf"|\({report_id}(?:, ?{report_id})*\)")


def files():
    for name in ("README.md", "CMakeLists.txt"):
        yield os.path.join(root, name)
    for folder in folders:
        for d, dirs, names in os.walk(os.path.join(root, folder)):
            dirs[:] = [x for x in dirs if not x.startswith(".") and x != "__pycache__"]
            for n in names:
                yield os.path.join(d, n)


found = []
for path in files():
    try:
        with open(path, encoding="utf-8") as f:
            lines = f.read().splitlines()
    except (UnicodeDecodeError, OSError):
        continue  # binary files (figures, HDF5, STL)
    if path.endswith(".svg"):
        continue  # drawn figures: colours and glyph ids only
    for i, line in enumerate(lines, 1):
        for m in tag.finditer(line):
            found.append(f"{os.path.relpath(path, root)}:{i}: '{m.group(0)}' in: {line.strip()[:120]}")
for line in found:
    print(line)
print(f"{len(found)} tracker or report tag(s) found" if found else "no tracker or report tags")
sys.exit(1 if found else 0)
