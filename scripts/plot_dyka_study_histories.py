#!/usr/bin/python3
"""Point-A velocity histories from the Dyka study's result files (molinos Figs. 8-10).

    /usr/bin/python3 scripts/plot_dyka_study_histories.py [--results DIR] [--mesh n133] [--out PNG]

Reads the .h5 files that `otmpm study examples/studies/dyka_coarse.toml` left in
examples/studies/dyka_coarse_results (probe A sampled every 1 us) and draws three
panels against the exact history: the gamma_lme sensitivity (LME 2, 3, 4 with NPC,
Fig. 8), LME against uGIMP (Fig. 9) and MPM against the OTM-style UL mode (Fig. 10).
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import numpy as np  # noqa: E402
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from plot_dyka_history import exact_velocity, read_result, self_check  # noqa: E402

PANELS = [
    ("gamma_lme sensitivity, MPM, NPC (cf. molinos Fig. 8)", ["mpm-lme2-npc", "mpm-lme3-npc", "mpm-lme4-npc"]),
    ("LME against uGIMP, MPM, NPC (cf. Fig. 9)", ["mpm-lme4-npc", "mpm-ugimp-npc"]),
    ("MPM against OTM-style UL, LME 4 (cf. Fig. 10)", ["mpm-lme4-npc", "ul-lme4-npc", "ul-lme4-otm"]),
]


def main(argv):
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--results", default=os.path.join(root, "examples", "studies", "dyka_coarse_results"))
    p.add_argument("--mesh", default="n133")
    p.add_argument("--out", default=os.path.join(root, "docs", "figures", "dyka_study_histories.png"))
    a = p.parse_args(argv)
    self_check()
    fig, axes = plt.subplots(len(PANELS), 1, figsize=(11, 11), sharex=True)
    for ax, (title, variants) in zip(axes, PANELS):
        first = None
        for i, v in enumerate(variants):
            r = read_result(os.path.join(a.results, f"{v}_{a.mesh}.h5"))
            err = np.sqrt(np.mean((r["v"] - exact_velocity(r["X"], r["t"])) ** 2))
            ax.plot(r["t"] * 1e6, r["v"], lw=1.3, color=f"C{i}", label=f"{v}: history error A {err:.4f} m/s")
            first = first or r
            print(f"{a.mesh} {v}: history error A {err:.4f} m/s, status {r['attrs'].get('status')}")
        tt = np.linspace(0.0, first["t"][-1], 20001)
        ax.plot(tt * 1e6, exact_velocity(first["X"], tt), "k", lw=1.0, label="exact")
        ax.set_title(f"{title}, h = L/{a.mesh[1:]}", fontsize=10)
        ax.set_ylabel("v of point A [m/s]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="lower center", ncol=2)
        ax.set_ylim(-6.5, 6.5)
    axes[-1].set_xlabel("time [us]")
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main(sys.argv[1:])
