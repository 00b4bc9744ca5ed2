#!/usr/bin/env python3
"""Accuracy of examples/stretch_bar.toml runs (docs/benchmarks.md, "Adapted
LME locality"): for each result file and output time, the deviation of the
particles from the homogeneous stretch the quasi-static bar approaches,
F_xx = 1 + v t / L (v = 1 m/s, L = 1 m):

  rms(F_xx - (1 + t))              spread of the axial stretch
  rms(x_p - X_p (1 + t)) / h       axial position error in grid spacings (h = 0.025)
  cv(sigma_xx)                     std / mean of the axial stress

  usage: stretch-bar-stats.py RESULT.h5 [...] --times 0.25 0.5
"""
import argparse

import h5py
import numpy as np

from tree_results import link_names

H = 0.025


def frames(f):
    """The frame names, sorted (link_names: safe on a killed run's file)."""
    return link_names(f["frames"])


def stats(path, times):
    rows = []
    with h5py.File(path, "r") as f:
        names = frames(f)
        x0 = f["frames"][names[0]]["x"][:, 0]
        for t in times:
            k = int(round(t / 0.05))
            if k >= len(names):
                rows.append((t, None))
                continue
            g = f["frames"][names[k]]
            Fxx = g["F"][:, 0]
            x = g["x"][:, 0]
            sxx = g["stress"][:, 0]
            rows.append((t, (np.sqrt(np.mean((Fxx - (1 + t)) ** 2)),
                             np.sqrt(np.mean((x - x0 * (1 + t)) ** 2)) / H,
                             np.std(sxx) / abs(np.mean(sxx)))))
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("files", nargs="+")
    ap.add_argument("--times", nargs="+", type=float, default=[0.25, 0.5])
    a = ap.parse_args()
    print("| file | t [s] | rms(F_xx - (1 + t)) | rms axial position error / h | cv(sigma_xx) |")
    print("|---|---|---|---|---|")
    for path in a.files:
        for t, r in stats(path, a.times):
            if r is None:
                print(f"| {path} | {t:g} | (failed before) | | |")
            else:
                print(f"| {path} | {t:g} | {r[0]:.3g} | {r[1]:.3g} | {r[2]:.3g} |")


if __name__ == "__main__":
    main()
