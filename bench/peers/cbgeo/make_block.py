#!/usr/bin/env python3
"""Write the CB-Geo mpm input of otmpm's 2D throughput block.

The block of bench/bench_scenes.hpp (block_scene, dimension 2): plane strain
linear elastic unit square (E = 1e7 Pa, nu = 0.3, rho = 1000 kg/m3), `cells`
cells across it (h = 1/cells), 2 x 2 particles per cell at the Gauss points
of the cell ((i + 1/2 -+ 1/(2 sqrt 3)) h: otmpm's default body.placement
"gauss"; --placement cell_centres gives (i + 1/4) h, (i + 3/4) h), gravity (0, -9.81), the grid nodes on y = 0
fixed in both directions.  The node lattice is otmpm's grid: x from -2h to
1 + 2h, y from 0 to 1 + 2h (cells + 4 by cells + 2 cells).  Particle volumes
are h^2 / 4 (CB-Geo's default: cell volume / particles in the cell).

Files written to OUT: mpm.json, mesh.txt, particles.txt, particles-cells.txt
(so CB-Geo does not search every cell for every particle at start-up) and
velocity-constraints.txt.  Standard library only.

    python3 make_block.py OUT [--cells 200] [--dt DT] [--nsteps N]
                              [--output-steps M] [--scheme usl|usf]
                              [--placement gauss|cell_centres]

dt defaults to otmpm's cfl step of the block: 0.3 h / c_p with the plane
strain P-wave speed c_p = sqrt(E (1 - nu) / ((1 + nu) (1 - 2 nu) rho)).
CB-Geo writes results/block/particles-*.h5 at every step s (0-based) with
s % output_steps == 0; the file of step s holds the state after s + 1 steps.
"""
import argparse
import json
import math
import os

E, NU, RHO, G = 1.0e7, 0.3, 1000.0, -9.81


def otmpm_dt(cells, cfl=0.3):
    h = 1.0 / cells
    cp = math.sqrt(E * (1 - NU) / ((1 + NU) * (1 - 2 * NU) * RHO))
    return cfl * h / cp


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", help="directory for the case (created)")
    ap.add_argument("--cells", type=int, default=200)
    ap.add_argument("--dt", type=float, default=None)
    ap.add_argument("--nsteps", type=int, default=10)
    ap.add_argument("--output-steps", type=int, default=None,
                    help="HDF5 output every M steps (default: nsteps - 1, "
                         "i.e. the first and the last step)")
    ap.add_argument("--scheme", default="usl", choices=["usl", "usf"])
    ap.add_argument("--placement", default="gauss",
                    choices=["gauss", "cell_centres"])
    a = ap.parse_args()

    n = a.cells
    h = 1.0 / n
    dt = a.dt if a.dt is not None else otmpm_dt(n)
    out_steps = a.output_steps if a.output_steps else max(1, a.nsteps - 1)
    os.makedirs(a.out, exist_ok=True)

    # Node lattice: i = 0..n+4 along x (x = (i - 2) h), j = 0..n+2 along y.
    nx, ny = n + 4, n + 2          # cells along x, y
    nnx = nx + 1                   # nodes along x
    lines = []
    for j in range(ny + 1):
        y = j * h
        for i in range(nnx):
            lines.append("%r %r" % ((i - 2) * h, y))
    cells = []
    for j in range(ny):
        for i in range(nx):
            n0 = j * nnx + i
            cells.append("%d %d %d %d" % (n0, n0 + 1, n0 + 1 + nnx, n0 + nnx))
    with open(os.path.join(a.out, "mesh.txt"), "w") as f:
        f.write("%d %d\n" % (len(lines), len(cells)))
        f.write("\n".join(lines))
        f.write("\n")
        f.write("\n".join(cells))
        f.write("\n")

    # Base nodes (y = 0): both directions fixed.
    with open(os.path.join(a.out, "velocity-constraints.txt"), "w") as f:
        for i in range(nnx):
            f.write("%d 0 0\n%d 1 0\n" % (i, i))

    # Particles: block cell (i, j) is grid cell (i + 2, j).
    if a.placement == "gauss":
        g = 0.5 / math.sqrt(3.0)
        offs = (0.5 - g, 0.5 + g)
    else:
        offs = (0.25, 0.75)
    parts, pc = [], []
    pid = 0
    for j in range(n):
        for i in range(n):
            cid = j * nx + i + 2
            for b in offs:
                for c in offs:
                    parts.append("%r %r" % ((i + c) * h, (j + b) * h))
                    pc.append("%d %d" % (pid, cid))
                    pid += 1
    with open(os.path.join(a.out, "particles.txt"), "w") as f:
        f.write("%d\n" % len(parts))
        f.write("\n".join(parts))
        f.write("\n")
    with open(os.path.join(a.out, "particles-cells.txt"), "w") as f:
        f.write("\n".join(pc))
        f.write("\n")

    cfg = {
        "title": "otmpm 2D block, %d x %d cells, 2x2 particles per cell" % (n, n),
        "mesh": {
            "mesh": "mesh.txt",
            "io_type": "Ascii2D",
            "check_duplicates": False,
            "isoparametric": False,
            "node_type": "N2D",
            "cell_type": "ED2Q4",
            "particle_cells": "particles-cells.txt",
            "boundary_conditions": {
                "velocity_constraints": [{"file": "velocity-constraints.txt"}]
            },
        },
        "particles": [{
            "group_id": 0,
            "generator": {
                "type": "file",
                "io_type": "Ascii2D",
                "location": "particles.txt",
                "check_duplicates": False,
                "particle_type": "P2D",
                "material_id": 0,
                "pset_id": 0,
            },
        }],
        "materials": [{
            "id": 0,
            "type": "LinearElastic2D",
            "density": RHO,
            "youngs_modulus": E,
            "poisson_ratio": NU,
        }],
        "external_loading_conditions": {"gravity": [0.0, G]},
        "analysis": {
            "type": "MPMExplicit2D",
            "mpm_scheme": a.scheme,
            "velocity_update": False,
            "locate_particles": True,
            "dt": dt,
            "nsteps": a.nsteps,
            "uuid": "block",
            "resume": {"resume": False},
        },
        "post_processing": {"path": "results/", "output_steps": out_steps},
    }
    with open(os.path.join(a.out, "mpm.json"), "w") as f:
        json.dump(cfg, f, indent=2)
    print("%s: %d nodes, %d cells, %d particles, dt = %r, nsteps = %d, "
          "scheme %s" % (a.out, len(lines), len(cells), len(parts), dt,
                         a.nsteps, a.scheme))


if __name__ == "__main__":
    main()
