#!/usr/bin/python3
"""A gamma_lme sweep on the Dyka bar (docs/benchmarks.md): the LME locality
parameter (beta = gamma_lme / h^2; small gamma = wide, smooth functions,
large gamma = close to the linear hat functions) at three mesh sizes, MPM with
NPC. Prints the RMS velocity error and the wall time of every run and draws
the work-precision plot (error against wall time, one line per gamma_lme
across the meshes):

    /usr/bin/python3 examples/python/gamma_sweep.py [--out DIR]

writes DIR/gamma_sweep_work_precision.png. No result files: the runs only
report their summary (write_results=False). One thread per run, so the wall
times compare (set OMP_NUM_THREADS as you like for your own sweeps).
"""
import argparse
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import otmpm  # noqa: E402

EXAMPLES = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GAMMAS = (1.5, 2.0, 3.0, 4.0, 6.0, 10.0)
MESHES = (20, 40, 133)  # h = L/20, L/40, L/133: examples/dyka/dyka_nN.toml
ERROR = "rms_velocity_error"


def sweep():
    """{gamma: [(mesh, wall seconds, error), ...]} over GAMMAS x MESHES."""
    table = {}
    for gamma in GAMMAS:
        for mesh in MESHES:
            scene = otmpm.Scene.from_toml(os.path.join(EXAMPLES, "dyka", f"dyka_n{mesh}.toml"),
                                          {"basis.gamma_lme": gamma})
            s = otmpm.run(scene, threads=1, write_results=False)
            print(f"gamma_lme = {gamma:4g}  h = L/{mesh:<4d} {s.status:3s} {s.steps:5d} steps "
                  f"{s.wall_seconds:7.3f} s  {ERROR} = {s.errors[ERROR]:.4f} m/s", flush=True)
            table.setdefault(gamma, []).append((mesh, s.wall_seconds, s.errors[ERROR]))
    return table


def plot(table, path):
    fig, ax = plt.subplots(figsize=(7, 5))
    colours = plt.cm.viridis([i / (len(table) - 1) for i in range(len(table))])
    for (gamma, rows), colour in zip(table.items(), colours):
        ax.loglog([r[1] for r in rows], [r[2] for r in rows], "o-", color=colour, label=f"gamma_lme = {gamma:g}")
    for i, mesh in enumerate(MESHES):  # the mesh size above the left end of its group of points
        wall = min(rows[i][1] for rows in table.values())
        error = max(rows[i][2] for rows in table.values())
        ax.annotate(f"h = L/{mesh}", (wall, error), textcoords="offset points", xytext=(0, 10), fontsize=9)
    ax.set(xlabel="wall time [s] (one thread)", ylabel=f"{ERROR} [m/s]",
           title="Dyka bar, MPM + LME + NPC: work-precision over gamma_lme")
    ax.grid(which="both", alpha=0.3)
    ax.margins(x=0.15, y=0.15)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print("plot:", path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=".", help="folder for the plot")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    plot(sweep(), os.path.join(args.out, "gamma_sweep_work_precision.png"))


if __name__ == "__main__":
    main()
