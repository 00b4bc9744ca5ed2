#!/usr/bin/env python3
"""Runs the two 2D molinos et al. benchmarks with otmpm and draws figures like the paper's.

  OMP_NUM_THREADS=1 /usr/bin/python3 scripts/plot_2d_benchmarks.py \
      [--otmpm build-rel/bin/otmpm] [--work DIR] [--reuse] [--small-plate]

Figures (docs/figures/):
  andersen_stress_depth.png  block under gravity: sigma_yy of every particle at
                             t_end against its initial height, vs -rho g (H - y)
                             (molinos sect. 3.2, Fig. 13), one panel per basis
  andersen_settlement.png    vertical displacement of the 'top' probe against
                             time, with the static settlement rho g H^2/(2E)
                             (molinos Fig. 14); an unstable run is marked by x
  plate_fe_npc.png           plate impact: |v| of every particle at matching
                             times, NPC (top row) vs FE (bottom row)
                             (molinos revised sect. 3.3, first figure)
  plate_wall_tangential.png  plate impact, NPC: the wall holding the normal
                             velocity only (the scene) vs both components,
                             and their difference
  plate_lme_perturbed.png    plate impact at t_end: LME and uGIMP on the
                             structured grid, LME on the perturbed grid; uGIMP
                             on the perturbed grid is refused (exit status 2)
                             and its message is printed in the panel

Every run is `otmpm run EXAMPLE --quiet --out FILE.h5 --set ...`. Exit status 1
(unstable) is a result: the file still holds the frames up to the stop. At the
end the script prints markdown tables of what it measured.
--reuse skips runs whose result file already exists.
--small-plate runs a 25 x 25 m plate instead of the paper's 50 x 50 m one.
"""
import argparse
import os
import shlex
import subprocess
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from tree_results import link_names  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXAMPLES = os.path.join(ROOT, "examples")
FIGURES = os.path.join(ROOT, "docs", "figures")

# Andersen block (examples/andersen_block.toml): rho, g, H, E.
RHO, G, H, YOUNG = 6000.0, 9.81, 10.0, 5.0e6
SETTLEMENT = RHO * G * H**2 / (2.0 * YOUNG)  # 0.589 m
SYY = 3  # sigma_yy column of a 2D stress row (D*D row-major)

ANDERSEN = {  # key: (label, overrides)
    "linear": ("linear (Q4), NPC", ["basis.kind=linear"]),
    "ugimp": ("uGIMP, NPC", ["basis.kind=ugimp", "body.block.placement=cell_centres"]),
    "lme08": ("LME gamma 0.8, NPC", ["basis.gamma_lme=0.8"]),
    "lme3": ("LME gamma 3, NPC", ["basis.gamma_lme=3.0"]),
    "linear_fe": ("linear (Q4), FE", ["basis.kind=linear", "simulation.integrator=fe"]),
}
ANDERSEN_PANELS = ["linear", "ugimp", "lme08", "lme3"]

PERTURBED = ["grid.kind=perturbed", "grid.perturbation=0.2"]
UGIMP_PLATE = ["basis.kind=ugimp", "body.plate.placement=cell_centres"]
STICK = ["boundary.wall.fix=[true,true]"]
PLATE = {
    "npc": ("LME gamma 3, NPC", []),
    "fe": ("LME gamma 3, FE", ["simulation.integrator=fe"]),
    "npc_stick": ("LME gamma 3, NPC, both components held", STICK),
    "fe_stick": ("LME gamma 3, FE, both components held", STICK + ["simulation.integrator=fe"]),
    "lme_pert": ("LME gamma 3, NPC, perturbed grid", PERTURBED),
    "ugimp": ("uGIMP, NPC", UGIMP_PLATE),
    "ugimp_pert": ("uGIMP, NPC, perturbed grid", UGIMP_PLATE + PERTURBED),
}
# Contact time of examples/plate_impact.toml: the leftmost particles (0.2113 h
# inside the plate's edge) reach the cells next to the wall (x = h = 1 m) at
# t = 1.596 s, after a free flight at 1 m/s; the figures are drawn at the
# paper's times after contact.
PLATE_CONTACT = 1.596
PLATE_TIMES = [PLATE_CONTACT + t for t in (0.798, 1.596, 2.66)]
# A 25 x 25 m plate on a grid that still leaves room for the wall and the rebound.
SMALL_PLATE = ["grid.upper=[33.0, 27.0]", "grid.cells=[33, 29]",
               "body.plate.upper=[27.384675134594813, 25.0]", "boundary.wall.upper=[0.0, 27.0]"]


def run(otmpm, scene, overrides, out, reuse):
    """Runs one scene; returns (exit status, stderr+stdout text)."""
    if reuse and os.path.exists(out):
        return None, "(reused)"
    cmd = [otmpm, "run", os.path.join(EXAMPLES, scene), "--quiet", "--out", out]
    for o in overrides:
        cmd += ["--set", o]
    print("$ OMP_NUM_THREADS=1 " + " ".join(shlex.quote(c) for c in cmd), flush=True)
    env = dict(os.environ, OMP_NUM_THREADS="1")
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    text = (p.stdout + p.stderr).strip()
    print(f"  exit {p.returncode}: {text}", flush=True)
    return p.returncode, text


def attrs(f):
    """(status, steps, wall_seconds) of a result file, each read by name (not dict(f.attrs): h5py lists
    attributes in name order, which crashes libhdf5 on a killed run's file)."""
    a = f.attrs
    status = a.get("status", b"?")
    return (status.decode() if isinstance(status, bytes) else str(status),
            int(a.get("steps", 0)), float(a.get("wall_seconds", float("nan"))))


def frames(f):
    """Frame groups sorted by time (their names; listed with link_names, safe on a killed run's file)."""
    g = f["frames"]
    return [g[k] for k in link_names(g)]


# ---------------------------------------------------------------- Andersen
def andersen(args):
    results = {}
    for key, (label, ov) in ANDERSEN.items():
        out = os.path.join(args.work, f"andersen_{key}.h5")
        rc, _ = run(args.otmpm, "andersen_block.toml", ov, out, args.reuse)
        with h5py.File(out, "r") as f:
            status, steps, wall = attrs(f)
            fr = frames(f)
            last = fr[-1]
            x, u, s = last["x"][:], last["displacement"][:], last["stress"][:]
            t_last = float(last.attrs["time"])
            y0 = x[:, 1] - u[:, 1]
            p = f["probes/top"]
            t, px = p["time"][:], p["x"][:]
        exact = -RHO * G * (H - y0)
        err = s[:, SYY] - exact
        results[key] = dict(label=label, status=status, steps=steps, wall=wall, rc=rc,
                            t_last=t_last, y0=y0, syy=s[:, SYY],
                            rms=float(np.sqrt(np.mean(err**2))),
                            t=t, settle=-(px[:, 1] - px[0, 1]), y_top0=float(px[0, 1]))
    plot_andersen_stress(results)
    plot_andersen_settlement(results)
    return results


def plot_andersen_stress(res):
    fig, axes = plt.subplots(1, len(ANDERSEN_PANELS), figsize=(16, 4.6), sharey=True)
    y = np.linspace(0.0, H, 50)
    for ax, key in zip(axes, ANDERSEN_PANELS):
        r = res[key]
        ax.plot(-RHO * G * (H - y) / 1e6, y, "k-", lw=1.5, label=r"exact $-\rho g (H-y)$")
        ax.plot(r["syy"] / 1e6, r["y0"], "o", ms=4, color="C3", label="particles")
        ax.set_title(f"{r['label']}\n{r['status']}, t = {r['t_last']:.2f} s, "
                     f"RMS err {r['rms'] / 1e3:.0f} kPa", fontsize=9)
        ax.set_xlabel(r"$\sigma_{yy}$ [MPa]")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("initial height y [m]")
    axes[0].legend(fontsize=8, loc="lower right")
    fig.suptitle("Block under gravity (molinos sect. 3.2): vertical stress at the last frame")
    fig.tight_layout()
    fig.savefig(os.path.join(FIGURES, "andersen_stress_depth.png"), dpi=110)
    plt.close(fig)


def plot_andersen_settlement(res):
    fig, ax = plt.subplots(figsize=(8, 4.8))
    for i, key in enumerate(ANDERSEN):
        r = res[key]
        style = "--" if key == "linear_fe" else "-"
        ax.plot(r["t"], r["settle"], style, marker=".", ms=4, color=f"C{i}",
                label=f"{r['label']} ({r['status']})")
        if r["status"] != "ok":
            ax.plot(r["t"][-1], r["settle"][-1], "x", ms=12, mew=3, color=f"C{i}")
    ax.axhline(SETTLEMENT, color="k", ls=":",
               label=rf"static $\rho g H^2/(2E)$ = {SETTLEMENT:.3f} m")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("settlement of probe 'top' [m]")
    ax.set_title("Block under gravity: vertical displacement of the top particle\n"
                 "(x marks a run that stopped as unstable)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(os.path.join(FIGURES, "andersen_settlement.png"), dpi=110)
    plt.close(fig)


# ------------------------------------------------------------------ plate
def load_plate(path):
    with h5py.File(path, "r") as f:
        status, steps, wall = attrs(f)
        fr = frames(f)
        snaps = [(float(g.attrs["time"]), g["x"][:], np.linalg.norm(g["v"][:], axis=1)) for g in fr]
        vel = [g["v"][:] for g in fr]
    return dict(status=status, steps=steps, wall=wall, snaps=snaps, vel=vel)


def nearest(snaps, t):
    return min(snaps, key=lambda s: abs(s[0] - t))


def scatter(ax, snap, title, vmax):
    t, x, vm = snap
    # Gouraud-shaded Delaunay triangulation of the particles: every particle keeps
    # its own value (no smoothing), and there are no gaps between markers.
    sc = ax.tripcolor(x[:, 0], x[:, 1], vm, shading="gouraud", cmap="jet", vmin=0.0, vmax=vmax)
    ax.set_title(f"{title}\nt = {t:.3f} s ({t - PLATE_CONTACT:.3f} s after contact)", fontsize=9)
    ax.set_aspect("equal")
    ax.axvline(0.0, color="k", lw=2)
    return sc


def plate(args):
    extra = SMALL_PLATE if args.small_plate else []
    res, refusal = {}, {}
    for key, (label, ov) in PLATE.items():
        out = os.path.join(args.work, f"plate_{key}.h5")
        rc, text = run(args.otmpm, "plate_impact.toml", extra + ov, out,
                       args.reuse and key != "ugimp_pert")
        if key == "ugimp_pert" and rc == 2:
            refusal = dict(rc=rc, text=text)
            continue
        res[key] = dict(label=label, rc=rc, **load_plate(out))
    vmax = max(float(nearest(res[k]["snaps"], t)[2].max()) for k in res for t in PLATE_TIMES)
    dmax = max(float(difference(res, "fe", "npc", t)[2].max()) for t in PLATE_TIMES)
    comparison_figure(res, "fe", "npc", vmax, dmax, "|v_FE - v_NPC|",
                      "Plate impact on a wall at x = 0 (molinos revised sect. 3.3): "
                      "NPC (top), FE (middle), their difference (bottom)", "plate_fe_npc.png")
    comparison_figure(res, "npc_stick", "npc", vmax, dmax, "|v_both - v_normal|",
                      "Plate impact, NPC: wall holding the normal velocity only (top, the scene), "
                      "both components (middle), their difference (bottom, same scale as FE - NPC)",
                      "plate_wall_tangential.png")

    fig, axes = plt.subplots(2, 2, figsize=(11, 10), sharex=True, sharey=True)
    order = [("npc", "LME gamma 3, structured grid"), ("lme_pert", "LME gamma 3, perturbed grid (0.2 h)"),
             ("ugimp", "uGIMP, structured grid"), (None, "uGIMP, perturbed grid")]
    for ax, (key, title) in zip(axes.flat, order):
        if key is None:
            msg = refusal.get("text", "(not refused?)")
            ax.text(0.5, 0.5, f"refused, exit status {refusal.get('rc', '?')}:\n\n" + wrap(msg, 48),
                    ha="center", va="center", fontsize=9, transform=ax.transAxes, family="monospace")
            ax.set_title(title, fontsize=9)
            continue
        sc = scatter(ax, nearest(res[key]["snaps"], PLATE_TIMES[-1]), title + f" ({res[key]['status']})", vmax)
    fig.colorbar(sc, ax=axes, label="|v| [m/s]", shrink=0.8)
    fig.suptitle("Plate impact, NPC, last frame: structured vs perturbed grid")
    fig.savefig(os.path.join(FIGURES, "plate_lme_perturbed.png"), dpi=100)
    plt.close(fig)
    return res, refusal


def comparison_figure(res, a, b, vmax, dmax, diff_label, title, name):
    """Runs b (top row) and a (middle row) at PLATE_TIMES, |v_a - v_b| (bottom row, colour scale dmax)."""
    fig, axes = plt.subplots(3, len(PLATE_TIMES), figsize=(13, 12.5), sharex=True, sharey=True)
    for row, key in enumerate([b, a]):
        for col, t in enumerate(PLATE_TIMES):
            sc = scatter(axes[row, col], nearest(res[key]["snaps"], t), res[key]["label"], vmax)
    fig.colorbar(sc, ax=axes[:2, :], label="|v| [m/s]", shrink=0.8)
    for col, t in enumerate(PLATE_TIMES):
        sd = scatter(axes[2, col], difference(res, a, b, t), diff_label + " (same particle)", dmax)
    fig.colorbar(sd, ax=axes[2, :], label=diff_label + " [m/s]", shrink=0.8)
    fig.suptitle(title)
    fig.savefig(os.path.join(FIGURES, name), dpi=100)
    plt.close(fig)


def difference(res, a, b, t):
    """(time, positions of run b, |v_a - v_b|) per particle at the frame of b nearest t."""
    tn, xn, _ = nearest(res[b]["snaps"], t)
    i = [s[0] for s in res[b]["snaps"]].index(tn)
    return tn, xn, np.linalg.norm(res[a]["vel"][i] - res[b]["vel"][i], axis=1)


def wrap(text, width):
    words, lines, cur = text.split(), [], ""
    for w in words:
        if len(cur) + len(w) + 1 > width:
            lines.append(cur)
            cur = w
        else:
            cur = (cur + " " + w).strip()
    return "\n".join(lines + [cur])


def plate_noise(res, key, t):
    """Spread of |v| in the undisturbed region is zero; report the std of |v| and max |v|."""
    _, x, vm = nearest(res[key]["snaps"], t)
    return float(vm.max()), float(np.std(vm))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--otmpm", default=os.path.join(ROOT, "build-rel", "bin", "otmpm"))
    ap.add_argument("--work", default=os.path.join("out", "2d"), help="folder of the result files (default: out/2d)")
    ap.add_argument("--reuse", action="store_true")
    ap.add_argument("--small-plate", action="store_true")
    ap.add_argument("--only", choices=["andersen", "plate"])
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    os.makedirs(FIGURES, exist_ok=True)
    if args.only != "plate":
        a = andersen(args)
        print("\n| run | status | steps | wall [s] | last t [s] | settlement at last t [m] | RMS sigma_yy error [kPa] | rel. to rho g H |")
        print("|---|---|---|---|---|---|---|---|")
        for r in a.values():
            print(f"| {r['label']} | {r['status']} | {r['steps']} | {r['wall']:.3f} | {r['t_last']:.2f} | "
                  f"{r['settle'][-1]:.4f} | {r['rms'] / 1e3:.1f} | {r['rms'] / (RHO * G * H):.4f} |")
        y = a["lme3"]["y_top0"]
        print(f"\nprobe 'top' starts at y = {y:.4f} m; exact static settlement there "
              f"{RHO * G / YOUNG * (H * y - y * y / 2):.4f} m")
    if args.only != "andersen":
        p, refusal = plate(args)
        print("\n| run | status | steps | wall [s] | " + " | ".join(
            f"max/std of abs(v) at {t} s" for t in PLATE_TIMES) + " |")
        print("|---|---|---|---|" + "---|" * len(PLATE_TIMES))
        for key, r in p.items():
            cells = " | ".join("%.3f / %.3f" % plate_noise(p, key, t) for t in PLATE_TIMES)
            print(f"| {r['label']} | {r['status']} | {r['steps']} | {r['wall']:.1f} | {cells} |")
        print("\nDifferences particle by particle, RMS / max of abs(v_a - v_b) [m/s]:\n")
        pairs = [("fe", "npc", "FE vs NPC (wall: normal only)"),
                 ("fe_stick", "npc_stick", "FE vs NPC (wall: both components)"),
                 ("npc_stick", "npc", "NPC: both components vs normal only"),
                 ("fe_stick", "fe", "FE: both components vs normal only")]
        print("| t [s] | t - t_contact [s] | " + " | ".join(p[2] for p in pairs) + " |")
        print("|---|---|" + "---|" * len(pairs))
        for t in PLATE_TIMES:
            cells = []
            for a, b, _ in pairs:
                tn, _, d = difference(p, a, b, t)
                cells.append(f"{np.sqrt(np.mean(d**2)):.4f} / {d.max():.4f}")
            print(f"| {tn:.3f} | {tn - PLATE_CONTACT:.3f} | " + " | ".join(cells) + " |")
        print(f"\nuGIMP on the perturbed grid: exit status {refusal.get('rc')}: {refusal.get('text')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
