#!/usr/bin/env python3
"""scripts/check-architecture.py refuses an include from a lower layer into a
higher one: in a copy of lib/otmpm, each folder of every layer but the top
gets an include of a header of every higher layer, one at a time; the check
must fail each time, naming the file, and pass on the untouched copy."""
import ast
import os
import shutil
import subprocess
import sys
import tempfile

here = os.path.dirname(os.path.abspath(__file__))
script = os.path.join(here, "..", "scripts", "check-architecture.py")
lib = os.path.join(here, "..", "lib", "otmpm")
# The script's own `layers = [...]` (a literal), so that the test follows the order it checks.
layers = next(ast.literal_eval(node.value) for node in ast.parse(open(script).read()).body
              if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "layers")


def run(root):
    return subprocess.run([sys.executable, script, root], capture_output=True, text=True)


def some_header(root, folder):
    d = root if folder == "core" else os.path.join(root, folder)
    return sorted(f for f in os.listdir(d) if f.endswith(".hpp"))[0]


failures = []
with tempfile.TemporaryDirectory() as tmp:
    root = os.path.join(tmp, "otmpm")
    shutil.copytree(lib, root)
    if run(root).returncode != 0:
        failures.append("the untouched copy fails the check")
    for low in range(len(layers) - 1):
        for folder in layers[low]:
            d = root if folder == "core" else os.path.join(root, folder)
            victim = os.path.join(d, some_header(root, folder))
            text = open(victim).read()
            for high in range(low + 1, len(layers)):
                target = layers[high][0]
                inc = f'#include "otmpm/{target}/{some_header(root, target)}"\n'
                open(victim, "w").write(inc + text)
                r = run(root)
                if r.returncode == 0 or "includes otmpm/" + target not in r.stdout:
                    failures.append(f"{folder}/ including {target}/ passed the check")
            open(victim, "w").write(text)
for f in failures:
    print("FAILED:", f)
print(f"{len(failures)} failures")
sys.exit(1 if failures else 0)
