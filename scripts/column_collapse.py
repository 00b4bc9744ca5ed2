#!/usr/bin/python3
"""Granular column collapse (docs/benchmarks.md, "Granular column collapse").

  measure: the normalised run-out (L_f - L0) / L0 and final height of result
           files of examples/column_collapse.toml, against the scaling of
           two-dimensional collapses (Lube et al. 2005: 1.2 a for a < 2.3,
           1.9 a^(2/3) above):
      /usr/bin/python3 scripts/column_collapse.py measure A.h5 [B.h5 ...]
  plot:    the final profiles (particles coloured by plastic strain), one
           panel per file, and the run-out against a:
      /usr/bin/python3 scripts/column_collapse.py plot --out docs/figures/column_collapse.png A.h5 ...

L0 and H0 are the column's box (body.column in the file's scene). The final
run-out L_f is the largest x of the particles at t_end plus the gap
L0 - max X between the outermost particle and the column's side at t = 0 (the tip of the deposit,
often a few particles sliding ahead alone); the deposit's front L_h is
where the deposit, from the back wall on, first thins to a single layer
of particles (largest particle y + half a particle spacing below 0.75 h, in
bins of half a cell h, 2 particles per cell). The final height H_f like L_f with y. a = H0 / L0.
"""
import argparse
import tomllib

import h5py
import numpy as np

from tree_results import link_names


def text(v):
    return v.decode() if isinstance(v, bytes) else v


def scaling(a):
    """The run-out (L_f - L0) / L0 of 2D collapses (Lube et al. 2005)."""
    a = np.asarray(a, dtype=float)
    return np.where(a < 2.3, 1.2 * a, 1.9 * a ** (2 / 3))


def measure(path):
    with h5py.File(path, "r") as f:
        scene = tomllib.loads(text(f.attrs["scene"]))
        body = scene["body"][0]
        L0 = body["upper"][0] - body["lower"][0]
        H0 = body["upper"][1] - body["lower"][1]
        names = link_names(f["frames"])  # not sorted(f["frames"]): safe on a killed run's file
        X = f["frames"][names[0]]["x"][:]
        last = f["frames"][names[-1]]
        x = last["x"][:]
        eps = last["plastic_strain"][:].ravel()
        e = f["energy"]
        s = scene["simulation"]
        g = scene["grid"]
        h = (g["upper"][0] - g["lower"][0]) / g["cells"][0]
        b = np.floor(x[:, 0] / (h / 2)).astype(int)
        top = np.full(b.max() + 1, -1.0)
        np.maximum.at(top, np.clip(b, 0, None), x[:, 1] + h / 4)
        thin = np.nonzero(top < 0.75 * h)[0]
        Lh = (thin[0] if len(thin) else len(top)) * h / 2
        return {
            "file": path, "mode": s.get("mode", "mpm"), "integrator": s["integrator"],
            "basis": scene["basis"]["kind"], "status": text(f.attrs["status"]), "t": float(last.attrs["time"]),
            "a": H0 / L0, "L0": L0, "H0": H0,
            "Lf": x[:, 0].max() + L0 - X[:, 0].max(), "Hf": x[:, 1].max() + H0 - X[:, 1].max(), "Lh": Lh, "h": h,
            "kinetic_end": float(e["kinetic"][-1]), "x": x, "eps": eps,
            # A killed run's file (status "running") has no summary attributes.
            "wall_seconds": float(f.attrs.get("wall_seconds", np.nan)), "particles": len(x),
            "steps": int(f.attrs.get("steps", -1)),
        }


def cmd_measure(a):
    for path in a.files:
        m = measure(path)
        r = (m["Lf"] - m["L0"]) / m["L0"]
        print(f"{path}: {m['mode']} {m['integrator']} {m['basis']} {m['status']} t = {m['t']:.3g} s, a = {m['a']:.3g}: "
              f"(L_f - L0)/L0 = {r:.3f}, front (L_h - L0)/L0 = {(m['Lh'] - m['L0']) / m['L0']:.3f} "
              f"(scaling {float(scaling(m['a'])):.3f}), H_f/H0 = {m['Hf'] / m['H0']:.3f}, "
              f"kinetic at t_end {m['kinetic_end']:.3g} J/m, {m['particles']} particles, {m['steps']} steps, "
              f"{m['wall_seconds']:.1f} s")


def cmd_plot(a):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ms = [measure(p) for p in a.files]
    labels = a.labels.split(";") if a.labels else [f"a = {m['a']:.3g}" for m in ms]
    fig = plt.figure(figsize=(12, 2.0 * len(ms) + 1.0), layout="constrained")
    gs = fig.add_gridspec(len(ms), 2, width_ratios=[3, 1.2])
    left = []
    x_max = max(1.6, 1.05 * max(m["Lf"] for m in ms))  # every tip in view
    for i, (m, label) in enumerate(zip(ms, labels)):
        ax = fig.add_subplot(gs[i, 0])
        left.append(ax)
        sc = ax.scatter(m["x"][:, 0], m["x"][:, 1], c=m["eps"], s=1.5, cmap="viridis", vmin=0, vmax=a.vmax,
                        rasterized=True)
        ax.plot([0, m["L0"], m["L0"]], [m["H0"], m["H0"], 0], "k:", lw=0.8)
        ax.axvline(m["L0"] * (1 + float(scaling(m["a"]))), color="tab:red", ls="--", lw=0.8)
        ax.set_xlim(-0.02, x_max)
        ax.set_ylim(-0.02, 0.82 if m["H0"] > 0.3 else 0.3)
        ax.set_aspect("equal")
        ax.axvline(m["Lh"], color="tab:blue", ls=":", lw=0.8)
        ax.set_title(f"{label}: tip (L_f - L0)/L0 = {(m['Lf'] - m['L0']) / m['L0']:.2f}, "
                     f"front (L_h - L0)/L0 = {(m['Lh'] - m['L0']) / m['L0']:.2f} (dotted), "
                     f"scaling {float(scaling(m['a'])):.2f} (dashed)", fontsize=7)
        ax.tick_params(labelsize=7)
    fig.colorbar(sc, ax=left, label="equivalent plastic strain", shrink=0.5, location="left")
    ax = fig.add_subplot(gs[:, 1])
    aa = np.linspace(0.3, 4.5, 100)
    ax.plot(aa, scaling(aa), "k-", label="Lube et al. 2005 (2D)")
    for m, label in zip(ms, labels):
        ax.plot(m["a"], (m["Lf"] - m["L0"]) / m["L0"], "o", label=label + " tip")
        ax.plot(m["a"], (m["Lh"] - m["L0"]) / m["L0"], "s", mfc="none", label=label + " front")
    ax.set_xlabel("a = H0 / L0")
    ax.set_ylabel("(L_f - L0) / L0")
    ax.legend(fontsize=6)
    ax.grid(alpha=0.3)
    fig.savefig(a.out, dpi=120)
    print("wrote", a.out)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("measure")
    m.add_argument("files", nargs="+")
    m.set_defaults(func=cmd_measure)
    g = sub.add_parser("plot")
    g.add_argument("files", nargs="+")
    g.add_argument("--out", required=True)
    g.add_argument("--labels")
    g.add_argument("--vmax", type=float, default=2.0)
    g.set_defaults(func=cmd_plot)
    a = p.parse_args()
    a.func(a)


if __name__ == "__main__":
    main()
