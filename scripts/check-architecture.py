#!/usr/bin/env python3
"""Checks the rules of docs/architecture.md ("Rules the layout keeps") on
lib/otmpm and prints the include dependencies between its folders (the
top-level headers count as folder 'core'):

1. no include loop between folders;
2. engine/ includes nothing of scene/, reference/, assembly/, run/ or io/;
3. no `friend` declaration;
4. no basis family named in a string outside basis/;
5. the class Engine<D> (engine/engine.hpp) is under 300 lines;
6. a folder includes only folders of its own layer or of a layer below it
   (`layers`, lowest first: the order of docs/architecture.md).

Exit status 1 when a rule is broken (each broken rule is printed)."""
import collections
import os
import re
import sys

# The tree checked: lib/otmpm, or the folder given as the only argument (a copy, tests).
root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib", "otmpm")
# The layers of docs/architecture.md ("The folders form layers"), lowest first.
layers = [
    ("core",),
    ("nodes", "particles", "materials", "geometry", "basis", "reference"),
    ("engine", "io"),
    ("integrators",),
    ("scene",),
    ("assembly",),
    ("distributed",),
    ("run",),
]
layer_of = {folder: i for i, group in enumerate(layers) for folder in group}
families = ("linear", "ugimp", "bspline2", "bspline3", "lme", "maxent")
deps = collections.defaultdict(set)
broken = []

for d, _, files in os.walk(root):
    folder = os.path.relpath(d, root)
    folder = "core" if folder == "." else folder
    for f in files:
        if not f.endswith((".cpp", ".hpp")):
            continue
        path = os.path.relpath(os.path.join(d, f), os.path.join(root, ".."))
        text = open(os.path.join(d, f)).read()
        for m in re.finditer(r'#include "otmpm/([^"]+)"', text):
            target = m.group(1).split("/")[0] if "/" in m.group(1) else "core"
            if target != folder:
                deps[folder].add(target)
            if folder not in layer_of or target not in layer_of:
                broken.append(f"{path}: folder '{folder if folder not in layer_of else target}' is in no layer")
            elif layer_of[target] > layer_of[folder]:
                broken.append(f"{path}: {folder}/ (layer {layer_of[folder]}) includes otmpm/{m.group(1)} "
                              f"(layer {layer_of[target]})")
            if folder == "engine" and target in ("scene", "reference", "assembly", "run", "io"):
                broken.append(f"{path}: engine/ includes otmpm/{m.group(1)}")
        code = re.sub(r"//.*", "", text)
        if re.search(r"\bfriend\b", code):
            broken.append(f"{path}: a friend declaration")
        if folder != "basis":
            for fam in families:
                if re.search(r'"%s"' % fam, code):
                    broken.append(f'{path}: the basis family "{fam}" named in a string outside basis/')

for k in sorted(deps):
    print(f"{k:12s} -> {', '.join(sorted(deps[k]))}")

loops = set()
def visit(node, path):
    for nxt in deps.get(node, ()):
        if nxt in path:
            loop = path[path.index(nxt):]
            i = loop.index(min(loop))
            loops.add(tuple(loop[i:] + loop[:i]))
        else:
            visit(nxt, path + [nxt])
for n in list(deps):
    visit(n, [n])
broken += ["include loop: " + " -> ".join(loop + (loop[0],)) for loop in sorted(loops)]

engine = open(os.path.join(root, "engine", "engine.hpp")).read().splitlines()
start = next(i for i, l in enumerate(engine) if l.startswith("template <int D> class Engine {"))
end = next(i for i in range(start, len(engine)) if engine[i] == "};")
print(f"class Engine<D>: {end - start + 1} lines")
if end - start + 1 >= 300:
    broken.append(f"engine/engine.hpp: class Engine<D> has {end - start + 1} lines (at most 300)")

for b in broken:
    print("BROKEN:", b)
sys.exit(1 if broken else 0)
