#!/usr/bin/env python3
"""Scaling plots of the performance tables: time per step against particle count (log-log).

    /usr/bin/python3 scripts/plot_scaling.py SCALING.csv OUT.png [TITLE]

SCALING.csv is written by `bench_table --scaling-csv` (2D block) or
`--scaling3d-csv` (3D block) (columns particles, seconds_per_step); TITLE
defaults to the 2D block's. The plot shows the measured points, the least-squares
power law t = c n^k (k printed in the legend) and the linear reference k = 1.
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def main(argv):
    if len(argv) not in (3, 4):
        sys.stderr.write(__doc__)
        return 2
    with open(argv[1], newline="") as f:
        rows = list(csv.DictReader(f))
    if len(rows) < 2:
        sys.stderr.write(f"{argv[1]}: need at least two rows\n")
        return 2
    n = np.array([float(r["particles"]) for r in rows])
    t = np.array([float(r["seconds_per_step"]) for r in rows])
    k, log_c = np.polyfit(np.log(n), np.log(t), 1)
    fig, ax = plt.subplots(figsize=(5.5, 4.0))
    ax.loglog(n, t, "o", label="measured (median)")
    ax.loglog(n, np.exp(log_c) * n**k, "-", label=f"fit: t ~ n^{k:.3f}")
    ax.loglog(n, t[0] * n / n[0], ":", color="grey", label="linear (k = 1)")
    ax.set_xlabel("particles")
    ax.set_ylabel("wall time per step (s)")
    ax.set_title(argv[3] if len(argv) == 4 else "2D block, linear basis, fe, mpm, one thread", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(argv[2], dpi=120)
    print(f"scaling exponent {k:.3f} over {n[0]:.0f}..{n[-1]:.0f} particles -> {argv[2]}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
