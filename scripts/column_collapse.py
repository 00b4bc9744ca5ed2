#!/usr/bin/python3
"""Granular column collapse (docs/benchmarks.md, "Granular column collapse").

  measure: the normalised run-out (L_f - L0) / L0 (tip and front), the final
           height H_f / H0 and the time of collapse of result files of
           examples/column_collapse.toml or column_collapse_mu_i.toml,
           against the scaling of two-dimensional collapses (Lube et al.
           2005, below); one line per file, --csv for a table:
      /usr/bin/python3 scripts/column_collapse.py measure [--csv] A.h5 [B.h5 ...]
  table:   the markdown table of docs/benchmarks.md (study result names
           VARIANT_MESH.h5), and whether the two finest meshes agree better
           with each other than with the scaling:
      /usr/bin/python3 scripts/column_collapse.py table examples/studies/column_collapse_results/*.h5
  plot:    the final profiles (particles coloured by plastic strain), one
           panel per file, and the run-out and height against a:
      /usr/bin/python3 scripts/column_collapse.py plot --out docs/figures/column_collapse.png A.h5 ...
  work-precision: the errors of the tip and of the final height against the
           scaling, largest over a, against the run time of the five a, one
           line per model (study result names MODEL-aA_MESH.h5):
      /usr/bin/python3 scripts/column_collapse.py work-precision --out WP.png RUN.h5 ...

  surface: how far the deposits of one column on finer and finer grids
           agree: the top surface (the highest particle + h/4 in bins of
           --bin metres from x = L0) of each file against the last (the
           finest), largest difference over the bins out to where the
           finest deposit is thinner than --thick metres; and each file's
           reach at that thickness, (L_t - L0) / L0 with L_t the outermost
           particle (+ h/4) of the last bin whose top is at least --thick
           high (the tip counts the film of one or two particles at the
           deposit's end, which thins and lengthens with the grid; L_t
           does not):
      /usr/bin/python3 scripts/column_collapse.py surface COARSE.h5 ... FINEST.h5

Scaling (Lube, Huppert, Sparks & Freundt 2005, Phys. Rev. E 72, 041301,
two-dimensional collapses in a channel): (L_f - L0) / L0 = 1.2 a for a small
and 1.9 a^(2/3) for a large (fits to a < 1.8 and a > 2.8; switched here at
2.3, where the two are 2.76 and 3.31); H_f / L0 = a (the top stays) for
a < 1.15 and a^(2/5) above, i.e. H_f / H0 = a^(-3/5).

L0 and H0 are the column's box (body.column in the file's scene). The final
run-out L_f is the largest x of the particles at t_end plus the gap
L0 - max X between the outermost particle and the column's side at t = 0 (the tip of the deposit,
often a few particles sliding ahead alone); the deposit's front L_h is
where the deposit, from the back wall on, first thins to a single layer
of particles (largest particle y + half a particle spacing below 0.75 h, in
bins of half a cell h, 2 particles per cell). The final height H_f like L_f
with y. The time of collapse t_c is the first output time from which the
tip stays within half a particle spacing (h/4) of its final place.
"""
import argparse
import csv
import math
import os
import sys
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


def height_scaling(a):
    """The final height H_f / H0 of 2D collapses (Lube et al. 2005)."""
    a = np.asarray(a, dtype=float)
    return np.where(a < 1.15, 1.0, a ** (-3 / 5))


def bin_index(x, width, start):
    """The bin of each abscissa x in bins of `width` from `start` (those before it in the first)."""
    return np.clip(np.floor((x - start) / width).astype(int), 0, None)


def deposit_top(x, h, width=None, start=0.0, empty=-1.0):
    """The deposit's top surface: (bin centres, largest y + h/4) in bins of
    `width` (h/2 unless given) from x = `start` (particles before it count in
    the first bin); `empty` where a bin holds no particle."""
    width = h / 2 if width is None else width
    b = bin_index(x[:, 0], width, start)
    top = np.full(b.max() + 1, empty)
    np.maximum.at(top, b, x[:, 1] + h / 4)
    return start + (np.arange(len(top)) + 0.5) * width, top


def open_result(path):
    """The result file `path` opened for reading, or exit with a message naming
    it (HDF5's lock refuses a file that a run is still writing)."""
    try:
        return h5py.File(path, "r")
    except BlockingIOError:
        sys.exit(f"column_collapse.py: {path}: a run is still writing it (HDF5 file lock); measure it when the run "
                 "has ended, or set HDF5_USE_FILE_LOCKING=FALSE to read the frames written so far")
    except OSError as e:
        sys.exit(f"column_collapse.py: {path}: cannot open it as a result file: {e}")


def measure(path):
    with open_result(path) as f:
        scene = tomllib.loads(text(f.attrs["scene"]))
        body = scene["body"][0]
        L0 = body["upper"][0] - body["lower"][0]
        H0 = body["upper"][1] - body["lower"][1]
        names = link_names(f["frames"])  # not sorted(f["frames"]): safe on a killed run's file
        X = f["frames"][names[0]]["x"][:]
        last = f["frames"][names[-1]]
        x = last["x"][:]
        eps = last["plastic_strain"][:].ravel() if "plastic_strain" in last else np.zeros(len(x))
        e = f["energy"]
        s = scene["simulation"]
        g = scene["grid"]
        h = g["h"] if "h" in g else (g["upper"][0] - g["lower"][0]) / g["cells"][0]
        h = h[0] if isinstance(h, list) else h
        _, top = deposit_top(x, h)
        thin = np.nonzero(top < 0.75 * h)[0]
        Lh = (thin[0] if len(thin) else len(top)) * h / 2
        gap = L0 - X[:, 0].max()
        Lf = x[:, 0].max() + gap
        times = np.array([float(f["frames"][n].attrs["time"]) for n in names])
        tips = np.array([f["frames"][n]["x"][:, 0].max() + gap for n in names])
        moving = np.nonzero(np.abs(tips - Lf) > h / 4)[0]  # the last frame is settled by definition
        tc = times[moving[-1] + 1] if len(moving) else times[0]
        material = next(m for m in scene["material"] if m["name"] == body["material"])
        a = H0 / L0
        Hf = x[:, 1].max() + H0 - X[:, 1].max()
        return {
            "file": path, "mode": s.get("mode", "mpm"), "integrator": s["integrator"], "model": material["model"],
            "basis": scene["basis"]["kind"], "status": text(f.attrs["status"]), "t": float(last.attrs["time"]),
            "a": a, "L0": L0, "H0": H0, "Lf": Lf, "Hf": Hf, "Lh": Lh, "h": h,
            "tip": (Lf - L0) / L0, "front": (Lh - L0) / L0, "height": Hf / H0,
            "tip_error": (Lf - L0) / L0 / float(scaling(a)) - 1, "height_error": Hf / H0 / float(height_scaling(a)) - 1,
            "t_c": tc, "t_c_scaled": tc / math.sqrt(H0 / 9.81),
            "kinetic_end": float(e["kinetic"][-1]), "x": x, "eps": eps,
            # A killed run's file (status "running") has no summary attributes.
            "wall_seconds": float(f.attrs.get("wall_seconds", np.nan)), "particles": len(x),
            "steps": int(f.attrs.get("steps", -1)),
        }


COLUMNS = ["file", "model", "a", "h", "status", "particles", "steps", "wall_seconds", "tip", "front", "height",
           "tip_error", "height_error", "t_c", "t_c_scaled", "kinetic_end"]


def cmd_measure(a):
    if a.csv:
        out = csv.writer(sys.stdout, lineterminator="\n")
        out.writerow(COLUMNS)
    for path in a.files:
        m = measure(path)
        if a.csv:
            out.writerow([m[c] if isinstance(m[c], str) else f"{m[c]:.6g}" for c in COLUMNS])
            continue
        print(f"{path}: {m['mode']} {m['integrator']} {m['basis']} {m['model']} {m['status']} t = {m['t']:.3g} s, "
              f"a = {m['a']:.3g}: (L_f - L0)/L0 = {m['tip']:.3f} (scaling {float(scaling(m['a'])):.3f}, "
              f"{100 * m['tip_error']:+.1f}%), front (L_h - L0)/L0 = {m['front']:.3f}, H_f/H0 = {m['height']:.3f} "
              f"(scaling {float(height_scaling(m['a'])):.3f}, {100 * m['height_error']:+.1f}%), "
              f"t_c = {m['t_c']:.3f} s = {m['t_c_scaled']:.2f} sqrt(H0/g), kinetic at t_end {m['kinetic_end']:.3g} J/m, "
              f"{m['particles']} particles, {m['steps']} steps, {m['wall_seconds']:.1f} s")


def study_name(path):
    """('mu_i-a2', 'L0-10') from a study result name such as mu_i-a2_L0-10.h5."""
    stem = os.path.basename(path).rsplit(".", 1)[0]
    variant, _, mesh = stem.rpartition("_")
    return variant, mesh


def surface_heights(m, width):
    """The deposit's top (largest y + h/4, 0 where no particle) in bins of `width` from x = L0 outward."""
    x = m["x"][m["x"][:, 0] >= m["L0"]]
    return deposit_top(x, m["h"], width, m["L0"], 0.0)[1] if len(x) else np.zeros(0)


def reach(m, top, width, thick):
    """(L_t - L0) / L0: L_t the largest x + h/4 of the particles in the last
    bin whose top is at least `thick` high (`top`: surface_heights(m,
    width)); L_t = L0 if none."""
    thick_bins = np.nonzero(top >= thick)[0]
    if not len(thick_bins):
        return 0.0
    x = m["x"][m["x"][:, 0] >= m["L0"], 0]  # the particles surface_heights bins
    last = x[bin_index(x, width, m["L0"]) == thick_bins[-1]]
    return (last.max() + m["h"] / 4 - m["L0"]) / m["L0"]


def cmd_surface(a):
    if len(a.files) < 2 or not (a.bin > 0 and a.thick > 0):
        sys.exit("column_collapse.py surface: give two or more result files (the finest last), --bin and --thick > 0")
    ms = [measure(path) for path in a.files]
    for path, m in zip(a.files, ms):
        if (m["L0"], m["H0"]) != (ms[-1]["L0"], ms[-1]["H0"]):
            sys.exit(f"column_collapse.py surface: {path} is a column of L0 = {m['L0']:g}, H0 = {m['H0']:g} m, "
                     f"{a.files[-1]} one of L0 = {ms[-1]['L0']:g}, H0 = {ms[-1]['H0']:g} m: compare one column")
    tops = [surface_heights(m, a.bin) for m in ms]
    finest = tops[-1]
    thin = np.nonzero(finest < a.thick)[0]
    bins = thin[0] if len(thin) else len(finest)
    print(f"{a.files[-1]}: h = {ms[-1]['h']:.4g} m, tip {ms[-1]['tip']:.3f}, reach at {a.thick:g} m "
          f"{reach(ms[-1], finest, a.bin, a.thick):.3f}; deposit thicker than {a.thick:g} m "
          f"from x = L0 over {bins} bins of {a.bin:g} m")
    for path, m, top in zip(a.files[:-1], ms[:-1], tops[:-1]):
        near = top[:bins]
        near = np.pad(near, (0, bins - len(near)))
        diff = np.abs(near - finest[:bins]).max() if bins else 0.0
        print(f"{path}: h = {m['h']:.4g} m, tip {m['tip']:.3f}, reach at {a.thick:g} m "
              f"{reach(m, top, a.bin, a.thick):.3f}: top surface within {1e3 * diff:.1f} mm "
              f"({diff / m['H0']:.3f} H0) of the finest")


def cmd_table(a):
    ms = [measure(p) for p in a.files]
    for m in ms:
        m["variant"] = f"{m['mode']} {m['model']}"
    ms.sort(key=lambda m: (m["variant"], m["a"], -m["h"]))
    print("| variant | a | h | particles | steps | wall [s] | tip (L_f - L0)/L0 | scaling | error | front | "
          "H_f / H0 | scaling | error | t_c / sqrt(H0/g) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for m in ms:
        h = f"L0/{round(m['L0'] / m['h'])}"
        if m["status"] != "ok":
            print(f"| {m['variant']} | {m['a']:g} | {h} | {m['particles']} | {m['steps']} | {m['wall_seconds']:.1f} | "
                  f"{m['status']} at t = {m['t']:.3g} s | | | | | | | |")
            continue
        print(f"| {m['variant']} | {m['a']:g} | {h} | {m['particles']} | {m['steps']} | {m['wall_seconds']:.1f} | "
              f"{m['tip']:.2f} | {float(scaling(m['a'])):.2f} | {100 * m['tip_error']:+.0f}% | {m['front']:.2f} | "
              f"{m['height']:.3f} | {float(height_scaling(m['a'])):.3f} | {100 * m['height_error']:+.0f}% | "
              f"{m['t_c_scaled']:.2f} |")
    # The acceptance: at the two finest meshes, each within 15% of the
    # scaling, and their difference smaller than the difference to it.
    print()
    finest = min(m["h"] for m in ms)
    for variant in sorted({m["variant"] for m in ms}):
        for aa in sorted({m["a"] for m in ms if m["variant"] == variant}):
            runs = sorted((m for m in ms if m["variant"] == variant and m["a"] == aa), key=lambda m: m["h"])
            if len(runs) < 2 or any(m["status"] != "ok" for m in runs[:2]) or runs[0]["h"] != finest:
                print(f"{variant} a = {aa:g}: the two finest meshes did not both finish")
                continue
            fine, next_ = runs[0], runs[1]
            for q, s in (("tip", scaling(aa)), ("height", height_scaling(aa))):
                both = max(abs(fine[q + "_error"]), abs(next_[q + "_error"])) <= 0.15
                converged = abs(fine[q] - next_[q]) < abs(fine[q] - float(s))
                print(f"{variant} a = {aa:g} {q}: L0/{round(fine['L0'] / fine['h'])} {fine[q]:.3f}, "
                      f"L0/{round(next_['L0'] / next_['h'])} {next_[q]:.3f}, scaling {float(s):.3f}: "
                      f"{'within' if both else 'NOT within'} 15% at both, difference between them "
                      f"{abs(fine[q] - next_[q]):.3f} {'<' if converged else '>='} {abs(fine[q] - float(s)):.3f} to the scaling")


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
        ax.axhline(m["H0"] * float(height_scaling(m["a"])), color="tab:red", ls="--", lw=0.8)
        ax.set_xlim(-0.02, x_max)
        ax.set_ylim(-0.02, max(0.3, 1.05 * m["H0"]))
        ax.set_aspect("equal")
        ax.axvline(m["Lh"], color="tab:blue", ls=":", lw=0.8)
        ax.set_title(f"{label}: tip (L_f - L0)/L0 = {m['tip']:.2f}, front {m['front']:.2f} (dotted), "
                     f"H_f/H0 = {m['height']:.2f}; scaling {float(scaling(m['a'])):.2f}, "
                     f"{float(height_scaling(m['a'])):.2f} (dashed)", fontsize=7)
        ax.tick_params(labelsize=7)
    fig.colorbar(sc, ax=left, label="equivalent plastic strain", shrink=0.5, location="left")
    aa = np.linspace(0.3, 1.05 * max(8.5, max(m["a"] for m in ms)), 200)
    ax = fig.add_subplot(gs[: max(1, len(ms) // 2), 1])
    ax.plot(aa, scaling(aa), "k-", label="Lube et al. 2005 (2D)")
    for m, label in zip(ms, labels):
        ax.plot(m["a"], m["tip"], "o", label=label + " tip")
    ax.set_ylabel("(L_f - L0) / L0")
    ax.legend(fontsize=6)
    ax.grid(alpha=0.3)
    ax = fig.add_subplot(gs[max(1, len(ms) // 2):, 1])
    ax.plot(aa, height_scaling(aa), "k-")
    for m in ms:
        ax.plot(m["a"], m["height"], "o")
    ax.set_xlabel("a = H0 / L0")
    ax.set_ylabel("H_f / H0")
    ax.grid(alpha=0.3)
    fig.savefig(a.out, dpi=120)
    print("wrote", a.out)


def cmd_work_precision(a):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = {}  # (model, mesh) -> measures
    for path in a.files:
        variant, mesh = study_name(path)
        m = measure(path)
        groups.setdefault((f"{m['mode']} {m['model']}", mesh), []).append(m)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4), sharex=True)
    for model in sorted({k[0] for k in groups}):
        pts = []
        for (mo, mesh), ms in groups.items():
            if mo != model or any(m["status"] != "ok" for m in ms):
                continue
            pts.append((sum(m["wall_seconds"] for m in ms), max(abs(m["tip_error"]) for m in ms),
                        max(abs(m["height_error"]) for m in ms), mesh))
        pts.sort()
        style = dict(marker="o", ls="--" if model.startswith("ul") else "-",
                     color="tab:blue" if model.endswith("mu_i") else "tab:orange", label=model)
        axes[0].loglog([p[0] for p in pts], [p[1] for p in pts], **style)
        axes[1].loglog([p[0] for p in pts], [p[2] for p in pts], **style)
        for p in pts:
            axes[0].annotate(p[3], (p[0], p[1]), fontsize=7)
            axes[1].annotate(p[3], (p[0], p[2]), fontsize=7)
    axes[0].set_ylabel("largest |tip error| over a against the scaling")
    axes[1].set_ylabel("largest |H_f error| over a against the scaling")
    for ax in axes:
        ax.axhline(0.15, color="k", ls=":", lw=0.8)
        ax.set_xlabel("wall time of the five a [s] (one core per run)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Granular column collapse: error against run time (a = 0.5, 1, 2, 4, 8; dotted: 15%)", fontsize=9)
    fig.tight_layout()
    fig.savefig(a.out, dpi=130)
    print("wrote", a.out)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("measure")
    m.add_argument("files", nargs="+")
    m.add_argument("--csv", action="store_true")
    m.set_defaults(func=cmd_measure)
    t = sub.add_parser("table")
    t.add_argument("files", nargs="+")
    t.set_defaults(func=cmd_table)
    g = sub.add_parser("plot")
    g.add_argument("files", nargs="+")
    g.add_argument("--out", required=True)
    g.add_argument("--labels")
    g.add_argument("--vmax", type=float, default=2.0)
    g.set_defaults(func=cmd_plot)
    f = sub.add_parser("surface")
    f.add_argument("files", nargs="+")
    f.add_argument("--bin", type=float, default=0.01)
    f.add_argument("--thick", type=float, default=0.01)
    f.set_defaults(func=cmd_surface)
    w = sub.add_parser("work-precision")
    w.add_argument("files", nargs="+")
    w.add_argument("--out", required=True)
    w.set_defaults(func=cmd_work_precision)
    a = p.parse_args()
    a.func(a)


if __name__ == "__main__":
    main()
