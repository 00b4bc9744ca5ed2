#!/usr/bin/python3
"""Sliding block (docs/benchmarks.md, "Sliding block"): the centre of mass of
the block of examples/sliding_block.toml against x(t) = 1/2 g (sin theta -
mu cos theta) t^2 at every frame, from result files:

    /usr/bin/python3 scripts/sliding_block.py sliding_block.h5 [more.h5 ...]

prints, per file, the relative error at t_end and the largest relative error
over the frames from t = 0.2 s on (before that the displacement is small and
the block's elastic settling under the suddenly applied gravity, of order
1e-4 m, is a large fraction of it).
"""
import math
import sys
import tomllib

import h5py
import numpy as np

from tree_results import link_names


def text(v):
    return v.decode() if isinstance(v, bytes) else v


def errors(path):
    with h5py.File(path, "r") as f:
        scene = tomllib.loads(text(f.attrs["scene"]))
        g = np.array(scene["body_force"]["value"])
        mu = scene["wall"][0]["friction"]
        gn = np.hypot(*g)
        theta = math.atan2(g[0], -g[1])
        acc = gn * (math.sin(theta) - mu * math.cos(theta))
        names = link_names(f["frames"])  # not sorted(f["frames"]): safe on a killed run's file
        X = f["frames"][names[0]]["x"][:, 0]
        m = f["frames"][names[0]]["mass"][:].ravel()
        rows = []
        for n in names[1:]:
            fr = f["frames"][n]
            t = float(fr.attrs["time"])
            ux = np.sum(m * (fr["x"][:, 0] - X)) / m.sum()
            rows.append((t, ux, 0.5 * acc * t * t))
        s = scene["simulation"]
        return s.get("mode", "mpm"), s["integrator"], scene["basis"]["kind"], rows


def main():
    for path in sys.argv[1:]:
        mode, integ, basis, rows = errors(path)
        rel = [abs(u - e) / e for t, u, e in rows if t >= 0.2 - 1e-12] or [float("nan")]
        t, u, e = rows[-1]
        print(f"{path}: {mode} {integ} {basis}: x({t:.3g}) = {u:.6f} m, exact {e:.6f} m, "
              f"error {100 * (u - e) / e:+.3f}%, largest |error| from t = 0.2 s: {100 * max(rel):.3f}%")


if __name__ == "__main__":
    main()
