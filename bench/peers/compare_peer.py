#!/usr/bin/env python3
"""The same figures of an otmpm result and a peer code's particle dump.

    compare_peer.py block  OTMPM.h5 PEER_DUMP
    compare_peer.py taylor OTMPM.h5 PEER_DUMP

OTMPM.h5: the result file of `otmpm run` (its last frame, fields x, v and,
for the block, stress); PEER_DUMP: a particle dump in the LAMMPS text form
(`ITEM: ATOMS` followed by the column names; Karamelo writes it). The
particles of the two codes need not be in the same order: the figures are
sums and extremes over all particles.

block: the particle count, the mean vertical velocity, the root mean square
speed, the mean vertical velocity and the mean sigma_yy of the particles
below y = 0.1 m. taylor: the particle count, the bar's length (largest minus
smallest z of a particle), the foot's radius (the largest distance from the
axis of a particle within 1 mm of the wall) and the mean vertical velocity.
Each figure is printed for both with their relative difference.
"""
import sys

import h5py
import numpy as np


def read_dump(path):
    """Columns of the last `ITEM: ATOMS` block of a LAMMPS-style dump."""
    with open(path) as f:
        lines = f.read().splitlines()
    starts = [i for i, line in enumerate(lines) if line.startswith("ITEM: ATOMS")]
    if not starts:
        sys.exit(f"{path}: no 'ITEM: ATOMS' line")
    i = starts[-1]
    names = lines[i].split()[2:]
    rows = []
    for line in lines[i + 1:]:
        if line.startswith("ITEM:"):
            break
        rows.append([float(v) for v in line.split()])
    data = np.array(rows)
    if data.ndim != 2 or data.shape[1] != len(names):
        sys.exit(f"{path}: the ATOMS block does not have the {len(names)} columns {names}")
    return {name: data[:, k] for k, name in enumerate(names)}


def read_otmpm(path):
    """The last frame of an otmpm result file: x, v (n x D) and stress if present."""
    with h5py.File(path, "r") as f:
        frames = sorted(f["frames"].keys())
        last = f["frames"][frames[-1]]
        out = {name: np.array(last[name]) for name in ("x", "v", "stress") if name in last}
    return out


def figures_block(x, y, vy, syy):
    low = y < 0.1
    return {
        "particles": len(x),
        "mean vy [m/s]": vy.mean(),
        "mean vy below y = 0.1 m [m/s]": vy[low].mean(),
        "mean sigma_yy below y = 0.1 m [Pa]": syy[low].mean(),
    }


def figures_taylor(x, y, z, vz):
    r = np.hypot(x, y)
    return {
        "particles": len(x),
        "length [mm]": 1e3 * (z.max() - z.min()),
        "foot radius [mm]": 1e3 * r[z < z.min() + 1e-3].max(),
        "mean vz [m/s]": vz.mean(),
    }


def main():
    if len(sys.argv) != 4 or sys.argv[1] not in ("block", "taylor"):
        sys.exit(__doc__)
    case, ours_path, peer_path = sys.argv[1:]
    ours, peer = read_otmpm(ours_path), read_dump(peer_path)
    if case == "block":
        if "stress" not in ours:
            sys.exit(f"{ours_path}: the last frame has no stress field")
        s = ours["stress"]  # n x 4 (xx, xy, yx, yy) or n x 2 x 2
        syy = s.reshape(len(s), -1)[:, 3]
        a = figures_block(ours["x"][:, 0], ours["x"][:, 1], ours["v"][:, 1], syy)
        b = figures_block(peer["x"], peer["y"], peer["vy"], peer["s22"])
    else:
        a = figures_taylor(ours["x"][:, 0], ours["x"][:, 1], ours["x"][:, 2], ours["v"][:, 2])
        b = figures_taylor(peer["x"], peer["y"], peer["z"], peer["vz"])
    print(f"{'figure':40s} {'otmpm':>14s} {'peer':>14s} {'difference':>11s}")
    for key in a:
        diff = (b[key] - a[key]) / abs(a[key]) if a[key] != 0 else float("nan")
        print(f"{key:40s} {a[key]:14.6g} {b[key]:14.6g} {diff:+11.2e}")


if __name__ == "__main__":
    main()
