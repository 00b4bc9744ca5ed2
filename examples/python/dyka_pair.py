#!/usr/bin/python3
"""The Dyka bar (docs/benchmarks.md) run as a pair: MPM (nodes on the fixed
grid, mode "mpm") and the OTM-style updated-Lagrangian scheme (nodes
advected with the material, mode "ul"), same LME basis and NPC integrator -
`otmpm pair` from Python. Prints the errors of both runs side by side and
plots the velocity history of point A (the free end) against the exact
solution:

    /usr/bin/python3 examples/python/dyka_pair.py [--mesh 133] [--out DIR]

writes DIR/dyka_pair_history.png and the result files DIR/dyka_pair_mpm.h5,
DIR/dyka_pair_ul.h5 (DIR: the current folder unless --out says another; the
script prints where). With the package built but not installed, set
PYTHONPATH=build/python first (or install it: pip install ., docs/python.md).
"""
import argparse
import math
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import otmpm  # noqa: E402

EXAMPLES = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def exact_velocity_A(scene, t):
    """v(0, t) of the bar, the d'Alembert solution at X = 0: the free end keeps
    the initial velocity V0 until the unloading wave from x = L/4 arrives
    (ct = L/4), rests until the wave reflected at the fixed end x = L arrives
    (ct = 7L/4), moves with -V0 until ct = 9L/4, rests again, and so on with
    period ct = 4L."""
    d = scene.to_dict()
    steel = d["material"][0]
    c = math.sqrt(steel["young"] / steel["density"])
    L = d["body"][0]["upper"][0]
    V0 = d["initial_velocity"][0]["velocity"][0]
    phase = np.mod(c * np.asarray(t) / L, 4.0)  # in bar lengths travelled
    return np.select([(phase < 0.25) | (phase >= 3.75), (phase >= 1.75) & (phase < 2.25)], [V0, -V0], 0.0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mesh", type=int, default=133, help="h = L/MESH (examples/dyka/dyka_nMESH.toml)")
    ap.add_argument("--out", default=".", help="folder for the plot and the result files")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    print(f"writing the result files and the plot into {os.path.abspath(args.out)}"
          + (" (the current folder; --out DIR for another)" if args.out == "." else ""))
    scene = otmpm.Scene.from_toml(os.path.join(EXAMPLES, "dyka", f"dyka_n{args.mesh}.toml"),
                                  {"output.every": 2e-7, "output.fields": ["x", "v"],
                                   "output.file": os.path.join(args.out, "dyka_pair.h5")})
    runs = otmpm.pair(scene, threads=1)

    print(f"{'':26s} {'mpm':>14s} {'ul':>14s}")
    for key in ("status", "steps", "wall_seconds", *runs["mpm"].errors, "max_energy_ratio", "energy_drift"):
        cells = [runs[m].errors.get(key, runs[m].get(key)) for m in otmpm.drivers.MODES]
        print(f"{key:26s} " + " ".join(f"{c:>14.5g}" if isinstance(c, float) else f"{c!s:>14s}" for c in cells))

    fig, ax = plt.subplots(figsize=(8, 4.5))
    t_exact = np.linspace(0.0, scene.t_end, 4001)
    ax.plot(t_exact * 1e6, exact_velocity_A(scene, t_exact), "k-", lw=1.2, label="exact")
    styles = {"mpm": dict(color="C0", lw=2.0, ls="-"), "ul": dict(color="C3", lw=1.0, ls="--")}
    for mode in otmpm.drivers.MODES:  # the two curves nearly coincide: ul dashed over mpm
        with otmpm.results.open(runs[mode].out_file) as r:
            A = r.probes["A"]
            label = f"{mode} (history error {runs[mode].errors['history_error_A']:.3f} m/s)"
            ax.plot(A["time"] * 1e6, A["v"][:, 0], label=label, **styles[mode])
    ax.set(xlabel="t [us]", ylabel="velocity of point A [m/s]",
           title=f"Dyka bar, h = L/{args.mesh}: {scene.basis} gamma_lme = {scene.to_dict()['basis']['gamma_lme']:g}, "
                 f"{scene.integrator}")
    ax.legend(loc="upper left")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    path = os.path.join(args.out, "dyka_pair_history.png")
    fig.savefig(path, dpi=120)
    print("plot:", os.path.abspath(path))
    print("result files:", ", ".join(os.path.abspath(runs[m].out_file) for m in otmpm.drivers.MODES))


if __name__ == "__main__":
    main()
