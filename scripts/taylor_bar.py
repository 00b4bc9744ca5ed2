#!/usr/bin/python3
"""Taylor bar (docs/benchmarks.md, "Taylor bar"): particles, grids, post-processing.

  particles: writes the quarter bar's particle file (x >= 0, y >= 0) for a
             grid spacing h, and prints the grid keys of that mesh:
      /usr/bin/python3 scripts/taylor_bar.py particles --h 0.8e-3 --out examples/taylor_bar/quarter_h0.8.csv
  measure:   final length, footprint radius, largest plastic strain and the
             energies of result files (one line per file; --csv for a table):
      /usr/bin/python3 scripts/taylor_bar.py measure RUN.h5 [RUN.h5 ...]
  work-precision: error of L_f and footprint against wall time, one line per
             variant (study result names VARIANT_MESH.h5; runs that failed left out):
      /usr/bin/python3 scripts/taylor_bar.py work-precision --reference REF.h5 --out WP.png RUN.h5 ...
  plot:      the deformed profiles (r, z) of result files, one panel each:
      /usr/bin/python3 scripts/taylor_bar.py plot --out docs/figures/taylor_bar.png A.h5 B.h5 ...

The bar: copper, L = 32.4 mm, R = 3.2 mm, along z from the wall z = 0. The
particles sit at the centres of sub-cells of size h/2 across (x, y) and
L / round(2 L / h) along z (2 per cell and axis), kept where the centre lies
in the quarter disk; the particles carry the exact quarter-bar mass
rho pi R^2 L / 4 (the staircase of kept sub-cells misses the volume by a few
per cent): by smaller volumes where the staircase is larger than the
disk, else by a `density` column (a volume above the sub-cell's would put
the particle's extent across the symmetry planes, outside the grid).

Measures (docs/benchmarks.md): the final length is the largest particle z
plus the gap L - max Z the particles start with (the half sub-cell between
the outermost particle and the bar's end); the footprint radius is the
largest sqrt(x^2 + y^2) of the particles in the bottom layer (z below
one sub-cell) plus the gap R - max_p sqrt(X^2 + Y^2) of the undeformed
bar; the largest plastic strain is the max over particles of the
`plastic_strain` field. The measures take the quarter bar and the full
cylinder (`shape = "cylinder"`, seeded about the axis x = y = 0) alike.
When the file has the fields `F` and `volume` (output.fields), the
measure adds the area-equivalent footprint radius R sqrt(A / A0): A and
A0 the deformed and the initial area of the bottom layer of particles,
each particle's share V0 (cof F)_zz and V0 - a measure of the whole rim,
not of its outermost particle.
"""
import argparse
import os
import csv
import math
import sys
import tomllib

import h5py
import numpy as np

L, R = 32.4e-3, 3.2e-3


def quarter_particles(h):
    """Positions (n x 3) and volumes (n) of the quarter bar for grid spacing h."""
    s = h / 2
    nr = math.ceil(R / s)
    nz = round(L / s)
    dz = L / nz
    c = (np.arange(nr) + 0.5) * s
    X, Y = np.meshgrid(c, c, indexing="ij")
    keep = X**2 + Y**2 < R**2
    xy = np.column_stack([X[keep], Y[keep]])
    z = (np.arange(nz) + 0.5) * dz
    pos = np.column_stack([np.repeat(xy, nz, axis=0), np.tile(z, len(xy))])
    scale = math.pi * R * R * L / 4 / (len(pos) * s * s * dz)
    if scale <= 1:  # the staircase holds more than the quarter disk: smaller volumes
        return pos, np.full(len(pos), scale * s * s * dz), None
    # A volume above s^2 dz would put the particle's extent across the
    # symmetry planes (outside the grid): a denser copper instead.
    return pos, np.full(len(pos), s * s * dz), np.full(len(pos), 8930.0 * scale)


def grid_keys(h):
    """lower, cells of a grid of spacing h: from the symmetry planes x = 0 and
    y = 0 to 14 mm across, from -2h to L + 2h along z."""
    lower = -2 * h
    cx = math.ceil(14e-3 / h - 1e-9)
    cz = math.ceil((L + 2 * h - lower) / h - 1e-9)
    return [0.0, 0.0, lower], [cx, cx, cz]


def cmd_particles(a):
    pos, V, rho = quarter_particles(a.h)
    with open(a.out, "w") as f:
        f.write("x,y,z,volume" + (",density" if rho is not None else "") + "\n")
        for i, (p, v) in enumerate(zip(pos, V)):
            extra = f",{rho[i]:.9g}" if rho is not None else ""
            f.write(f"{p[0]:.9g},{p[1]:.9g},{p[2]:.9g},{v:.9g}{extra}\n")
    lower, cells = grid_keys(a.h)
    upper = [lo + n * a.h for lo, n in zip(lower, cells)]
    print(f"# {len(pos)} particles in {a.out}")
    print(f'set = ["grid.lower=[{lower[0]:.9g}, {lower[1]:.9g}, {lower[2]:.9g}]", '
          f'"grid.upper=[{upper[0]:.9g}, {upper[1]:.9g}, {upper[2]:.9g}]", '
          f'"grid.cells=[{cells[0]}, {cells[1]}, {cells[2]}]"]')


def text(v):
    return v.decode() if isinstance(v, bytes) else v


def footprint_area(X, V0, F):
    """The area-equivalent footprint radius R sqrt(A / A0): A and A0 the
    deformed and initial area of the particles' bottom layer (those at the
    lowest Z), each particle's share V0 (cof F)_zz and V0, (cof F)_zz =
    J (F^-1)_zz the area ratio of a face normal to z."""
    Z = X[:, 2]
    above = Z[Z > Z.min() + 1e-9 * L]
    layer = Z < (0.5 * (Z.min() + above.min()) if above.size else np.inf)
    F = F.reshape(-1, 3, 3)[layer]
    cof_zz = np.linalg.det(F) * np.linalg.inv(F)[:, 2, 2]
    return R * math.sqrt((V0[layer] * cof_zz).sum() / V0[layer].sum())


def measure(path):
    """The Taylor bar measures of one result file (a dict)."""
    with h5py.File(path, "r") as f:
        a = f.attrs
        names = sorted(f["frames"])
        first, last = f["frames"][names[0]], f["frames"][names[-1]]
        X, x = first["x"][:], last["x"][:]
        if len(names) < 2:  # a run that stopped before its last frame: no final shape
            x = np.full_like(X, np.nan)
        eps = last["plastic_strain"][:].ravel() if "plastic_strain" in last else np.full(len(x), np.nan)
        area_r = footprint_area(X, first["volume"][:].ravel(), last["F"][:]) \
            if "volume" in first and "F" in last and len(names) > 1 else np.nan
        e = f["energy"]
        ek, es = e["kinetic"][:], e["strain"][:]
        wd = e["dissipated"][:] if "dissipated" in e else np.zeros_like(ek)
        w = e["external_work"][:] + e["reaction_work"][:]
        scene = tomllib.loads(text(a["scene"]))
        s = 2 * np.abs(X[:, 0]).min()  # the sub-cell across (particles at its centres, x = 0 a cell face)
        r0 = np.hypot(X[:, 0], X[:, 1])
        bottom = x[:, 2] < x[:, 2].min() + s
        E0 = ek[0] + es[0]
        return {
            "file": path,
            "mode": scene["simulation"].get("mode", "mpm"),
            "integrator": scene["simulation"]["integrator"],
            "basis": scene["basis"]["kind"],
            "status": text(a["status"]),
            "t": float(last.attrs["time"]),
            "particles": int(a["particles"]),
            "steps": int(a["steps"]),
            "wall_seconds": float(a["wall_seconds"]),
            "length_mm": 1e3 * (x[:, 2].max() + L - X[:, 2].max()),
            "footprint_mm": 1e3 * (np.hypot(x[bottom, 0], x[bottom, 1]).max() + R - r0.max()) if bottom.any() else np.nan,
            "footprint_area_mm": 1e3 * area_r,
            "max_plastic_strain": float(np.nanmax(eps)),
            "E0": E0,
            "kinetic_end": ek[-1] / E0,
            "strain_end": es[-1] / E0,
            "plastic_work": wd[-1] / E0,
            "integrator_loss": (E0 + w[-1] - ek[-1] - es[-1] - wd[-1]) / E0,
        }


COLUMNS = ["mode", "integrator", "basis", "status", "particles", "steps", "wall_seconds", "length_mm",
           "footprint_mm", "max_plastic_strain", "kinetic_end", "strain_end", "plastic_work", "integrator_loss",
           "footprint_area_mm"]


def cmd_measure(a):
    out = csv.writer(sys.stdout, lineterminator="\n")
    if a.csv:
        out.writerow(["file"] + COLUMNS)
    for path in a.files:
        m = measure(path)
        if a.csv:
            out.writerow([path] + [f"{m[c]:.6g}" if isinstance(m[c], float) else str(m[c]) for c in COLUMNS])
        else:
            print(f"{path}: {m['status']} t = {m['t'] * 1e6:.1f} us, {m['particles']} particles, {m['steps']} steps, "
                  f"{m['wall_seconds']:.1f} s | L_f = {m['length_mm']:.2f} mm, footprint = {m['footprint_mm']:.2f} mm, "
                  f"max eps_p = {m['max_plastic_strain']:.2f} | of E0: kinetic {m['kinetic_end']:.4f}, "
                  f"elastic {m['strain_end']:.4f}, plastic {m['plastic_work']:.4f}, "
                  f"integrator {m['integrator_loss']:.4f}"
                  + (f" | area-equivalent footprint {m['footprint_area_mm']:.2f} mm"
                     if math.isfinite(m['footprint_area_mm']) else ""))


def cmd_plot(a):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(a.files)
    fig, axes = plt.subplots(1, n, figsize=(2.6 * n + 0.8, 5.2), sharey=True, squeeze=False)
    labels = a.labels.split(";") if a.labels else a.files
    for ax, path, label in zip(axes[0], a.files, labels):
        with h5py.File(path, "r") as f:
            names = sorted(f["frames"])
            last = f["frames"][names[-1]]
            x = last["x"][:]
            eps = last["plastic_strain"][:].ravel()
        m = measure(path)
        r = np.hypot(x[:, 0], x[:, 1])
        order = np.argsort(eps)
        sc = ax.scatter(1e3 * r[order], 1e3 * x[order, 2], c=eps[order], s=2, cmap="viridis", vmin=0,
                        vmax=a.vmax, rasterized=True)
        ax.plot([0, R * 1e3, R * 1e3], [L * 1e3, L * 1e3, 0], "k:", lw=0.8, label="initial bar")
        for y in (21.4, 21.7):
            ax.axhline(y, color="tab:red", lw=0.6, ls="--")
        for xr in (7.0, 7.2):
            ax.axvline(xr, color="tab:red", lw=0.6, ls="--")
        ax.set_title(f"{label}\nL_f {m['length_mm']:.2f}, r_f {m['footprint_mm']:.2f} mm", fontsize=8)
        ax.set_xlabel("r [mm]")
        ax.set_xlim(0, 9)
        ax.set_ylim(-0.5, 33.5)
        ax.set_aspect("equal")
    axes[0][0].set_ylabel("z [mm]")
    axes[0][0].legend(loc="upper right", fontsize=7)
    fig.colorbar(sc, ax=axes[0].tolist(), label="equivalent plastic strain", shrink=0.8)
    fig.suptitle("Taylor bar at 80 us (dashed: published L_f 21.4-21.7 mm, r_f 7.0-7.2 mm)", fontsize=9)
    fig.savefig(a.out, dpi=130)
    print("wrote", a.out)


def variant_of(path):
    """'mpm-lme-npc' from a study result name such as mpm-lme-npc_R3.h5."""
    stem = os.path.basename(path).rsplit(".", 1)[0]
    return stem.rpartition("_")[0] or stem


def cmd_work_precision(a):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ref = measure(a.reference)
    runs = {}
    for path in a.files:
        m = measure(path)
        name = variant_of(path)
        if m["status"] == "ok" and os.path.abspath(path) != os.path.abspath(a.reference):
            runs.setdefault(name, []).append(m)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6), sharex=True)
    markers = {"fe": "o", "musl": "s", "npc": "^"}
    for name in sorted(runs):
        ms = sorted(runs[name], key=lambda m: m["wall_seconds"])
        mode, basis, integ = ms[0]["mode"], ms[0]["basis"], ms[0]["integrator"]
        style = dict(marker=markers.get(integ, "x"), ls="-" if mode == "mpm" else "--",
                     color={"linear": "tab:blue", "lme": "tab:orange"}.get(basis, "k"),
                     alpha=0.55 + 0.15 * list(markers).index(integ) if integ in markers else 1.0, label=name)
        t = [m["wall_seconds"] for m in ms]
        axes[0].loglog(t, [max(abs(m["length_mm"] - ref["length_mm"]), 1e-3) for m in ms], **style)
        axes[1].loglog(t, [max(abs(m["footprint_mm"] - ref["footprint_mm"]), 1e-3) for m in ms], **style)
    axes[0].set_ylabel(f"|L_f - L_ref| [mm] (L_ref = {ref['length_mm']:.2f} mm)")
    axes[1].set_ylabel(f"|r_f - r_ref| [mm] (r_ref = {ref['footprint_mm']:.2f} mm)")
    for ax in axes:
        ax.set_xlabel("wall time [s] (one core per run)")
        ax.grid(True, which="both", alpha=0.3)
    axes[1].legend(fontsize=7, ncol=2, loc="lower left")
    fig.suptitle(f"Taylor bar: error against run time (h = R/2, R/3, R/4; reference {os.path.basename(a.reference)}; "
                 "solid mpm, dashed ul)", fontsize=9)
    fig.tight_layout()
    fig.savefig(a.out, dpi=130)
    print("wrote", a.out)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    q = sub.add_parser("particles")
    q.add_argument("--h", type=float, required=True)
    q.add_argument("--out", required=True)
    q.set_defaults(func=cmd_particles)
    m = sub.add_parser("measure")
    m.add_argument("files", nargs="+")
    m.add_argument("--csv", action="store_true")
    m.set_defaults(func=cmd_measure)
    g = sub.add_parser("plot")
    g.add_argument("files", nargs="+")
    g.add_argument("--out", required=True)
    g.add_argument("--labels", help="panel titles separated by ';'")
    g.add_argument("--vmax", type=float, default=3.0)
    g.set_defaults(func=cmd_plot)
    w = sub.add_parser("work-precision")
    w.add_argument("files", nargs="+")
    w.add_argument("--reference", required=True, help="the result file whose L_f and footprint are the reference")
    w.add_argument("--out", required=True)
    w.set_defaults(func=cmd_work_precision)
    a = p.parse_args()
    a.func(a)


if __name__ == "__main__":
    sys.exit(main())
