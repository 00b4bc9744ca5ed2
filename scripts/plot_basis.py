#!/usr/bin/python3
"""Shape functions and their derivatives in 1D, molinos Figs. 4/5 style.

Evaluates every basis family with `otmpm basis` on [0, 1] with 10 cells
(nodes every 0.1) and plots the shape function of the node at x = 0.5 and of
its neighbours:

    docs/figures/basis_functions.png    N_I(x)
    docs/figures/basis_derivatives.png  dN_I/dx

Families: linear, uGIMP (2 particles per cell, half-width h/4), LME with
gamma_lme = 0.8, 1.5, 3, 4, 10 (beta = gamma_lme / h^2, our convention, docs/theory.md)
and B-splines of degree 2 and 3 (their control points sit at the Greville
abscissae, so degree 2 has no control point at 0.5: the two nearest are shown).

    python3 scripts/plot_basis.py --otmpm build/bin/otmpm
    python3 scripts/plot_basis.py --csv-dir /tmp/basis --no-run   # re-plot saved CSVs
"""
import argparse
import csv
import os
import subprocess
import sys
import tempfile
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

LOWER, UPPER, CELLS = 0.0, 1.0, 10
H = (UPPER - LOWER) / CELLS
CENTRE = 0.5
SAMPLES = 2001  # sample spacing h/200: resolves the kinks of linear and uGIMP
UGIMP_PPC = 2
LME_GAMMAS = (0.8, 1.5, 3.0, 4.0, 10.0)
# Neighbours drawn: nodes within this distance of the centre node.
NEIGHBOUR_RADIUS = 1.01 * H


def runs():
    """(label, file stem, otmpm basis options) for every curve set."""
    out = [
        ("linear", "linear", ["--kind", "linear"]),
        (f"uGIMP ({UGIMP_PPC} ppc)", "ugimp", ["--kind", "ugimp", "--ppc", str(UGIMP_PPC)]),
        ("B-spline p=2", "bspline2", ["--kind", "bspline2"]),
        ("B-spline p=3", "bspline3", ["--kind", "bspline3"]),
    ]
    for g in LME_GAMMAS:
        out.append((f"LME $\\gamma$={g:g}", f"lme_{g:g}", ["--kind", "lme", "--gamma-lme", repr(g)]))
    return out


def evaluate(otmpm, csv_path, options):
    cmd = [otmpm, "basis", *options, "--lower", str(LOWER), "--upper", str(UPPER), "--cells", str(CELLS),
           "--samples", str(SAMPLES), "--out", csv_path]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit(f"plot_basis: {' '.join(cmd)} failed ({res.returncode}):\n{res.stderr}")


def read_csv(path):
    """{node position: (x, N, dN)} with zeros where the node is outside the stencil."""
    xs = {}
    per_node = defaultdict(dict)
    with open(path) as f:
        for row in csv.DictReader(f):
            p = int(row["point"])
            xs[p] = float(row["x0"])
            per_node[float(row["xI0"])][p] = (float(row["N"]), float(row["dN0"]))
    points = sorted(xs)
    x = np.array([xs[p] for p in points])
    curves = {}
    for xi, vals in per_node.items():
        N = np.array([vals.get(p, (0.0, 0.0))[0] for p in points])
        dN = np.array([vals.get(p, (0.0, 0.0))[1] for p in points])
        curves[xi] = (x, N, dN)
    return curves


def check_partition_of_unity(name, curves):
    """sum_I N_I = 1 at every sample: a wrong CSV would make a wrong figure."""
    total = sum(c[1] for c in curves.values())
    err = np.max(np.abs(total - 1.0))
    if err > 1e-6:  # LME truncates its support at exp(-beta r^2) = 1e-6 and renormalises
        sys.exit(f"plot_basis: {name}: sum of N differs from 1 by {err:.2e}")


def centre_and_neighbours(curves):
    nodes = sorted(curves)
    centre = min(nodes, key=lambda xi: (abs(xi - CENTRE), xi))
    neighbours = [xi for xi in nodes if xi != centre and abs(xi - centre) <= NEIGHBOUR_RADIUS]
    return centre, neighbours


def draw_family(ax, curves, which, colour, label, neighbours=True, style="-"):
    col = 1 if which == "N" else 2
    centre, nbs = centre_and_neighbours(curves)
    c = curves[centre]
    ax.plot(c[0], c[col], style, color=colour, lw=2.0, label=f"{label}, $x_I$={centre:.2f}")
    if neighbours:
        for xi in nbs:
            c = curves[xi]
            ax.plot(c[0], c[col], style, color=colour, lw=0.9, alpha=0.55)


def decorate(ax, which, title):
    ax.set_title(title, fontsize=10)
    ax.set_xlim(0.15, 0.85)
    for k in range(CELLS + 1):
        ax.axvline(LOWER + k * H, color="0.88", lw=0.6, zorder=0)
    ax.axhline(0.0, color="0.6", lw=0.6, zorder=0)
    ax.set_xlabel("x")
    ax.set_ylabel("$N_I(x)$" if which == "N" else "$dN_I/dx$")
    ax.legend(fontsize=7, loc="upper right" if which == "N" else "lower left", framealpha=0.9)


def figure(data, which, path):
    fig, axes = plt.subplots(2, 3, figsize=(14, 8.2), constrained_layout=True)
    gam_colours = plt.cm.viridis(np.linspace(0.0, 0.9, len(LME_GAMMAS)))
    draw_family(axes[0, 0], data["linear"], which, "C0", "linear")
    decorate(axes[0, 0], which, "(a) linear (thin: neighbours)")
    draw_family(axes[0, 1], data["ugimp"], which, "C1", f"uGIMP, {UGIMP_PPC} ppc")
    draw_family(axes[0, 1], data["linear"], which, "0.5", "linear", neighbours=False, style="--")
    decorate(axes[0, 1], which, f"(b) uGIMP, half-width h/{2 * UGIMP_PPC} (thin: neighbours)")
    draw_family(axes[0, 2], data["bspline2"], which, "C2", "B-spline p=2")
    draw_family(axes[0, 2], data["bspline3"], which, "C3", "B-spline p=3")
    decorate(axes[0, 2], which, "(c) B-splines, control points at Greville abscissae")
    for g, colour in zip(LME_GAMMAS, gam_colours):
        draw_family(axes[1, 0], data[f"lme_{g:g}"], which, colour, f"LME $\\gamma$={g:g}", neighbours=False)
    draw_family(axes[1, 0], data["linear"], which, "0.5", "linear", neighbours=False, style="--")
    decorate(axes[1, 0], which, "(d) LME, node at x = 0.5, $\\beta = \\gamma/h^2$")
    for panel, g in ((axes[1, 1], 0.8), (axes[1, 2], 4.0)):
        draw_family(panel, data[f"lme_{g:g}"], which, gam_colours[LME_GAMMAS.index(g)], f"LME $\\gamma$={g:g}")
        decorate(panel, which, f"({'e' if g < 1 else 'f'}) LME $\\gamma$={g:g} (thin: neighbours)")
    what = "Shape functions $N_I$" if which == "N" else "Derivatives $dN_I/dx$"
    fig.suptitle(f"{what} in 1D, nodes every h = {H:g} on [{LOWER:g}, {UPPER:g}] "
                 "(cf. molinos et al. Fig. 4)", fontsize=12)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote {path}")


def main(argv):
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(here)
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--otmpm", default=os.path.join(root, "build", "bin", "otmpm"), help="the otmpm executable")
    p.add_argument("--csv-dir", help="keep the CSVs here (default: a temporary directory)")
    p.add_argument("--no-run", action="store_true", help="read existing CSVs from --csv-dir instead of running otmpm")
    p.add_argument("--out-dir", default=os.path.join(root, "docs", "figures"))
    a = p.parse_args(argv)
    if a.no_run and not a.csv_dir:
        p.error("--no-run needs --csv-dir")
    with tempfile.TemporaryDirectory() as tmp:
        csv_dir = a.csv_dir or tmp
        os.makedirs(csv_dir, exist_ok=True)
        data = {}
        for label, stem, options in runs():
            path = os.path.join(csv_dir, f"basis_{stem}.csv")
            if not a.no_run:
                evaluate(a.otmpm, path, options)
            data[stem] = read_csv(path)
            check_partition_of_unity(label, data[stem])
        os.makedirs(a.out_dir, exist_ok=True)
        figure(data, "N", os.path.join(a.out_dir, "basis_functions.png"))
        figure(data, "dN", os.path.join(a.out_dir, "basis_derivatives.png"))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
