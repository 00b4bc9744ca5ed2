#!/usr/bin/python3
"""Energy histories of the two-disk collision (docs/benchmarks.md, benchmark 3).

Usage: plot_disks.py OUT.png LABEL=RESULT.h5 [LABEL=RESULT.h5 ...]

Reads /energy/{time,kinetic,strain} of each result file (otmpm run
examples/disks.toml with and without [contact]), plots kinetic, strain and
total energy against time and prints the total energy loss
(E(0) - E(t_end)) / E(0) of each run.
"""
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt


def main():
    out, runs = sys.argv[1], [a.split("=", 1) for a in sys.argv[2:]]
    fig, axes = plt.subplots(1, len(runs), figsize=(5.5 * len(runs), 4), sharey=True, squeeze=False)
    for ax, (label, path) in zip(axes[0], runs):
        with h5py.File(path, "r") as f:
            t = f["energy/time"][:]
            kin, strain = f["energy/kinetic"][:], f["energy/strain"][:]
        total = kin + strain
        loss = (total[0] - total[-1]) / total[0]
        print(f"{label}: E(0) = {total[0]:.6g} J/m, E(t_end) = {total[-1]:.6g} J/m, "
              f"loss = {100 * loss:.2f}% at t = {t[-1]:.3g} s, max E / E(0) = {total.max() / total[0]:.6f}")
        ax.plot(t, kin, label="kinetic")
        ax.plot(t, strain, label="strain")
        ax.plot(t, total, "k", label="total")
        ax.set_title(f"{label}: total energy loss {100 * loss:.1f}%")
        ax.set_xlabel("t [s]")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("energy per unit thickness [J/m]")
    axes[0][0].legend()
    fig.tight_layout()
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main()
