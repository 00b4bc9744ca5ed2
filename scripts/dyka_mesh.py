#!/usr/bin/python3
"""Grid options of the Dyka bar at mesh size h = L/n (docs/benchmarks.md).

The mpm grid ends at x = L and reaches two cells left of x = 0:
grid.lower = -2h, grid.cells = n + 2.

    scripts/dyka_mesh.py 133
        prints  --set grid.cells=[135] --set grid.lower=[-0.002004511278195489]
        for use as:  otmpm run examples/dyka.toml $(scripts/dyka_mesh.py 133)

    scripts/dyka_mesh.py --write-scenes examples/dyka
        (re)writes examples/dyka/dyka_nN.toml for the seven mesh sizes of the
        paper from examples/dyka.toml.
"""
import argparse
import os
import re
import sys

L = 0.1333  # bar length [m]
PAPER_MESHES = (13, 20, 40, 133, 267, 401, 1333)
# Fine meshes write a frame every 2 us instead of every 1 us (smaller files).
FINE_MESH = 401
FINE_EVERY = 2.0e-6


def grid(n):
    """(cells, lower) of the 1D mpm grid for h = L/n."""
    if n < 1:
        raise ValueError(f"n must be >= 1 (got {n})")
    h = L / n
    return n + 2, -2.0 * h


def set_options(n):
    cells, lower = grid(n)
    return [f"--set grid.cells=[{cells}]", f"--set grid.lower=[{lower!r}]"]


def scene_text(template, n):
    """examples/dyka.toml with the grid, output file and frame interval for n.

    The template's leading comment block is replaced by one for this mesh."""
    cells, lower = grid(n)
    body = re.sub(r"\A(?:#[^\n]*\n|\n)*", "", template)
    every = FINE_EVERY if n >= FINE_MESH else None
    header = (
        f"# Dyka bar (molinos et al., sect. 3.1; docs/benchmarks.md) at mesh size\n"
        f"# h = L/{n} = {L / n * 1e3:.4g} mm, L = 0.1333 m: examples/dyka.toml with the grid\n"
        f"# reaching two cells left of x = 0 (lower = -2h, cells = n + 2 = {cells})"
        + (f"\n# and a frame every {FINE_EVERY:g} s to keep the result file small" if every else "")
        + ".\n"
        f"# Written by: python3 scripts/dyka_mesh.py --write-scenes examples/dyka\n"
        f"#\n"
        f"#   otmpm run examples/dyka/dyka_n{n}.toml                                # LME gamma_lme = 4, NPC\n"
        f"#   otmpm run examples/dyka/dyka_n{n}.toml --set simulation.integrator=fe\n"
        f"#   otmpm pair examples/dyka/dyka_n{n}.toml                               # MPM and UL\n\n"
    )
    subs = [
        (r"(?m)^lower = \[-[0-9.eE+-]+\]$", f"lower = [{lower!r}]"),
        (r"(?m)^cells = \[\d+\]$", f"cells = [{cells}]"),
        (r'(?m)^file = "dyka\.h5"$', f'file = "dyka_n{n}.h5"'),
    ]
    if every:
        subs.append((r"(?m)^every = [0-9.eE+-]+$", f"every = {every:.1e}"))
    for pattern, repl in subs:
        body, count = re.subn(pattern, repl, body)
        if count != 1:
            raise RuntimeError(f"template: expected one match of {pattern!r}, found {count}")
    return header + body


def write_scenes(directory, template_path):
    with open(template_path) as f:
        template = f.read()
    os.makedirs(directory, exist_ok=True)
    for n in PAPER_MESHES:
        path = os.path.join(directory, f"dyka_n{n}.toml")
        with open(path, "w") as f:
            f.write(scene_text(template, n))
        print(f"wrote {path}")


def main(argv):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("n", nargs="?", type=int, help="mesh size h = L/n")
    p.add_argument("--write-scenes", metavar="DIR", help="write the seven scene files into DIR")
    p.add_argument("--template", default=os.path.join(os.path.dirname(__file__), "..", "examples", "dyka.toml"))
    a = p.parse_args(argv)
    if a.write_scenes:
        write_scenes(a.write_scenes, a.template)
        return 0
    if a.n is None:
        p.error("give n (h = L/n) or --write-scenes DIR")
    if a.n < 1:
        p.error(f"n must be >= 1 (got {a.n})")
    print(" ".join(set_options(a.n)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
