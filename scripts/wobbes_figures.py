#!/usr/bin/env python3
"""Runs the three wobbes et al. benchmarks with otmpm and draws figures like the paper's.

  /usr/bin/python3 scripts/wobbes_figures.py [--otmpm PATH] [--work DIR] [--reuse]

Figures (docs/figures/wobbes_*.png):
  wobbes_fixed_bar_stress.png       fixed bar, sigma at t_end (wobbes Fig. 5)
  wobbes_fixed_bar_convergence.png  fixed bar, RMS displacement error vs nodes (Fig. 6)
  wobbes_traction_bar.png           traction bar, u and sigma at t_end, end velocity (Fig. 7)
  wobbes_traction_bar_stability.png BSMPM with consistent mass vs unified (sect. 8.2)
  wobbes_mms_plate.png              MMS plate, sigma_11 along X_2 ~ 0.07 m (Fig. 9)

Every run is `otmpm run EXAMPLE --set ... --out FILE.h5 --quiet` with
OMP_NUM_THREADS=1; the script prints each command and, at the end, markdown
tables of the measured errors and the timing table (wobbes Table 1: wall time
relative to MPM-linear, median of 3 repetitions, measured in this run).
--reuse skips runs whose result file already exists (never for the timings).
"""
import argparse
import glob
import json
import os
import shlex
import statistics
import subprocess
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXAMPLES = os.path.join(ROOT, "examples")
FIGURES = os.path.join(ROOT, "docs", "figures")

# --------------------------------------------------------------------------
# Methods: (label, overrides). Mass is always given explicitly, because the
# example files set their own default (mms_plate.toml sets consistent).
MPM = ["simulation.mode=mpm", "simulation.integrator=fe"]
OTM = ["simulation.mode=ul", "simulation.integrator=otm", "simulation.mass=consistent"]
UNIFIED = ["simulation.mode=ul", "simulation.integrator=unified", "simulation.mass=consistent",
           "basis.kind=bspline2"]
LUMPED = ["simulation.mass=lumped"]
CONSISTENT = ["simulation.mass=consistent"]

METHODS = {
    "mpm_linear": ("MPM-linear", MPM + LUMPED + ["basis.kind=linear"]),
    "otm_linear": ("OTM-linear", OTM + ["basis.kind=linear"]),
    "mpm_lme": ("MPM-LME (gamma 4)", MPM + LUMPED + ["basis.kind=lme"]),
    "mpm_lme_cons": ("MPM-LME, consistent mass", MPM + CONSISTENT + ["basis.kind=lme"]),
    "mpm_maxent": ("MPM-maxent (d_max 2)", MPM + LUMPED + ["basis.kind=maxent", "basis.d_max=2"]),
    "mpm_maxent_cons": ("MPM-maxent, consistent mass", MPM + CONSISTENT + ["basis.kind=maxent", "basis.d_max=2"]),
    "otm_maxent": ("OTM-maxent (d_max 2)", OTM + ["basis.kind=maxent", "basis.d_max=2"]),
    "bsmpm": ("BSMPM (bspline2, lumped)", MPM + LUMPED + ["basis.kind=bspline2"]),
    "bsmpm_cons": ("BSMPM (bspline2, consistent)", MPM + CONSISTENT + ["basis.kind=bspline2"]),
    "unified": ("unified (bspline2)", UNIFIED),
}

STYLE = {
    "mpm_linear": dict(color="tab:red", marker="o"),
    "otm_linear": dict(color="tab:blue", marker="s"),
    "mpm_lme": dict(color="tab:olive", marker="v"),
    "mpm_lme_cons": dict(color="tab:olive", marker="v", linestyle="--", markerfacecolor="none"),
    "mpm_maxent": dict(color="tab:purple", marker="^"),
    "mpm_maxent_cons": dict(color="tab:purple", marker="^", linestyle="--", markerfacecolor="none"),
    "otm_maxent": dict(color="tab:cyan", marker="D"),
    "bsmpm": dict(color="tab:orange", marker="x"),
    "bsmpm_cons": dict(color="tab:orange", marker="P", linestyle="--"),
    "unified": dict(color="tab:green", marker="*", markersize=9),
}

# MMS plate: the manufactured u_1 depends on X_1 only and u_2 on X_2 only, so it
# is not zero tangentially on the edges; only the normal component is fixed
# ("rollers"), which is what the exact solution satisfies.
MMS_ROLLERS = ["boundary.left.fix=[true,false]", "boundary.right.fix=[true,false]",
               "boundary.bottom.fix=[false,true]", "boundary.top.fix=[false,true]"]
# The same edges with both components fixed ("fixed at the entire boundary").
MMS_PINNED = ["boundary.left.fix=[true,true]", "boundary.right.fix=[true,true]",
              "boundary.bottom.fix=[true,true]", "boundary.top.fix=[true,true]"]


class Runner:
    """Runs otmpm and caches the result files under `work`."""

    def __init__(self, otmpm, work, reuse):
        self.otmpm, self.work, self.reuse = otmpm, work, reuse
        os.makedirs(work, exist_ok=True)
        self.env = dict(os.environ, OMP_NUM_THREADS="1")

    def command(self, example, overrides, out):
        cmd = [self.otmpm, "run", os.path.join(EXAMPLES, example)]
        for o in overrides:
            cmd += ["--set", o]
        return cmd + ["--out", out, "--quiet"]

    def run(self, tag, example, overrides, reuse=None):
        out = os.path.join(self.work, tag + ".h5")
        reuse = self.reuse if reuse is None else reuse
        if not (reuse and os.path.exists(out)):
            cmd = self.command(example, overrides, out)
            print("$ OMP_NUM_THREADS=1 " + " ".join(shlex.quote(c) for c in cmd), flush=True)
            # exit code 1 = the run stopped as unstable; its result file is valid.
            rc = subprocess.run(cmd, env=self.env).returncode
            if rc not in (0, 1):
                sys.exit(f"otmpm failed with exit code {rc}: {' '.join(cmd)}")
        return Result(out)


class Result:
    """The parts of an otmpm result file the figures use."""

    def __init__(self, path):
        with h5py.File(path, "r") as f:
            self.attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()}
            keys = sorted(f["frames"].keys())
            self.frames = []
            for k in keys:
                g = f["frames"][k]
                self.frames.append({"time": float(g.attrs["time"]),
                                    **{n: g[n][:] for n in g.keys()}})
            self.probes = {}
            if "probes" in f:
                for name, g in f["probes"].items():
                    self.probes[name] = {n: g[n][:] for n in g.keys()}

    @property
    def status(self):
        return str(self.attrs.get("status", "?"))

    def error(self, name):
        return float(self.attrs.get(name, np.nan))

    def last(self):
        return self.frames[-1]

    def first(self):
        return self.frames[0]


# --------------------------------------------------------------------------
# Exact solutions (the same formulas as lib/otmpm/reference/exact.cpp)

def fixed_bar_exact(X, t, E=4.0e3, rho=1.0, L=1.0, v0=0.6):
    c = np.sqrt(E / rho)
    w = np.pi * c / L
    u = v0 / w * np.sin(w * t) * np.sin(np.pi * X / L)
    sigma = E * v0 / c * np.sin(w * t) * np.cos(np.pi * X / L)
    return u, sigma


def traction_bar_exact(X, t, E=100.0, rho=100.0, L=1.0, tau0=1.0):
    """Displacement, velocity, stress of wobbes eq. 103 (small strain)."""
    c = np.sqrt(E / rho)
    om = np.pi / L
    s = np.mod(c * t, 4 * L)
    X = np.asarray(X, dtype=float)
    s = np.broadcast_to(s, X.shape) if np.ndim(s) == 0 else s
    alpha, vel = tau0 / (E * om), c * tau0 / E
    a, b = om * (s + X), om * (s - X)
    conds = [s < L - X, s < L + X, s < 3 * L - X, s < 3 * L + X]
    u = np.select(conds, [0 * X, -alpha * (1 + np.cos(a)), alpha * (np.cos(b) - np.cos(a)),
                          alpha * (1 + np.cos(b))], 0 * X)
    v = np.select(conds, [0 * X, vel * np.sin(a), vel * (np.sin(a) - np.sin(b)), -vel * np.sin(b)], 0 * X)
    sig = np.select(conds, [0 * X, tau0 * np.sin(a), tau0 * (np.sin(a) + np.sin(b)), tau0 * np.sin(b)], 0 * X)
    return u, v, sig


def mms_sigma11(X1, X2, t, E=1.0e7, nu=0.3, rho0=1.0e7, A=0.005, L=1.0):
    """Cauchy sigma_11 of the manufactured plate (wobbes eqs. 104-105, neo-Hookean)."""
    c = np.sqrt(E / rho0)
    mu = E / (2 * (1 + nu))
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    kx, kt = 2 * np.pi / L, c * np.pi / L
    F11 = 1 + A * kx * np.cos(kx * X1) * np.sin(kt * t)
    F22 = 1 - A * kx * np.cos(kx * X2) * np.sin(kt * t)
    J = F11 * F22
    P11 = mu * (F11 - 1 / F11) + lam * np.log(J) / F11
    return P11 * F11 / J


# --------------------------------------------------------------------------
# Fixed-end bar (wobbes 8.1)

FB_NODES = [8, 16, 32, 64, 128, 256, 512]
FB_CONVERGENCE = ["mpm_linear", "otm_linear", "mpm_lme", "mpm_maxent", "otm_maxent", "bsmpm",
                  "bsmpm_cons", "unified", "mpm_lme_cons", "mpm_maxent_cons"]


def fixed_bar(runner, summary):
    errors = {}
    for key in FB_CONVERGENCE:
        label, ov = METHODS[key]
        errors[key] = []
        for n in FB_NODES:
            r = runner.run(f"fb_{key}_{n}", "fixed_bar.toml", ov + [f"grid.cells=[{n - 1}]"])
            errors[key].append(r.error("rms_displacement_error") if r.status == "ok" else np.nan)
    summary["fixed_bar"] = {"nodes": FB_NODES, "rms_displacement_error": errors}

    # Convergence plot (wobbes Fig. 6): the paper's methods left, the mass
    # matrix variants right.
    fig, axes = plt.subplots(1, 2, figsize=(12, 5), sharey=True)
    groups = [["mpm_linear", "otm_linear", "mpm_lme", "mpm_maxent", "otm_maxent", "bsmpm_cons", "unified"],
              ["mpm_linear", "bsmpm", "bsmpm_cons", "mpm_lme", "mpm_lme_cons", "mpm_maxent", "mpm_maxent_cons"]]
    titles = ["methods of wobbes Fig. 6 (BSMPM with consistent mass)", "lumped vs consistent mass in MPM"]
    n = np.array(FB_NODES, float)
    for ax, group, title in zip(axes, groups, titles):
        for key in group:
            ax.loglog(n, errors[key], label=METHODS[key][0], **STYLE[key])
        for order, y0, ls in [(2, 3e-6, ":"), (3, 3e-7, "-.")]:
            ax.loglog(n[:5], y0 * (n[:5] / n[0]) ** (-order), "k" + ls, lw=1, label=f"order {order}")
        ax.set_xlabel("nodes (cells + 1)")
        ax.set_title(title, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_ylabel("RMS displacement error at t_end [m]")
    fig.suptitle("Fixed-end bar (wobbes 8.1): spatial convergence, t_end = 1 ms, dt = 1e-5 s, 12 particles/cell")
    fig.tight_layout()
    fig.savefig(os.path.join(FIGURES, "wobbes_fixed_bar_convergence.png"), dpi=120)
    plt.close(fig)

    # Stress profiles at t_end (wobbes Fig. 5), with a zoom on the left end
    # (the result files of the convergence runs above).
    runs = {"mpm_linear": runner.run("fb_mpm_linear_512", "fixed_bar.toml",
                                     METHODS["mpm_linear"][1] + ["grid.cells=[511]"], reuse=True),
            "otm_linear": runner.run("fb_otm_linear_512", "fixed_bar.toml",
                                     METHODS["otm_linear"][1] + ["grid.cells=[511]"], reuse=True),
            "unified": runner.run("fb_unified_32", "fixed_bar.toml", METHODS["unified"][1] + ["grid.cells=[31]"],
                                  reuse=True)}
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.6))
    panels = [(axes[0], ["mpm_linear", "otm_linear"], "512 nodes", None),
              (axes[1], ["mpm_linear", "otm_linear"], "512 nodes, zoom", (0.0, 0.12)),
              (axes[2], ["unified"], "32 nodes", None)]
    for ax, keys, title, zoom in panels:
        t = runs[keys[0]].last()["time"]
        Xe = np.linspace(0, 1, 2000)
        ue, se = fixed_bar_exact(Xe, t)
        ax.plot(Xe + ue, se, "k-", lw=1, label="exact", zorder=1)
        for key in keys:
            fr = runs[key].last()
            ax.plot(fr["x"][:, 0], fr["stress"][:, 0], ".", ms=2.5 if key != "unified" else 3.5,
                    color=STYLE[key]["color"], label=METHODS[key][0], zorder=2)
        if zoom:
            ax.set_xlim(*zoom)
            ax.set_ylim(6.4, 8.4)
        ax.set_xlabel("x [m]")
        ax.set_title(f"{title}, t = {t * 1e3:.1f} ms", fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, markerscale=3)
    axes[0].set_ylabel("sigma [Pa]")
    fig.suptitle("Fixed-end bar: stress at t_end (wobbes Fig. 5)")
    fig.tight_layout()
    fig.savefig(os.path.join(FIGURES, "wobbes_fixed_bar_stress.png"), dpi=120)
    plt.close(fig)
    for key, r in runs.items():
        fr = r.last()
        X = (fr["x"] - fr["displacement"])[:, 0]
        _, se = fixed_bar_exact(X, fr["time"])
        summary.setdefault("fixed_bar_stress_profile", {})[key] = {
            "nodes": int(r.attrs["nodes"]), "rms_stress_error": r.error("rms_stress_error"),
            "max_stress_error": float(np.abs(fr["stress"][:, 0] - se).max()),
            "stress_amplitude": float(np.abs(se).max())}


# --------------------------------------------------------------------------
# Bar with a dynamic traction (wobbes 8.2)

TB_METHODS = ["mpm_linear", "bsmpm", "mpm_maxent", "otm_linear", "otm_maxent", "unified"]
TB_FINE_OUTPUT = ["output.every=0.002"]


def traction_bar(runner, summary):
    runs = {k: runner.run(f"tb_{k}", "traction_bar.toml", METHODS[k][1] + TB_FINE_OUTPUT) for k in TB_METHODS}
    rows = {}
    fig, axes = plt.subplots(2, 2, figsize=(14, 9))
    ax_mpm, ax_ul, ax_u, ax_v = axes[0, 0], axes[0, 1], axes[1, 0], axes[1, 1]
    t = runs["mpm_linear"].last()["time"]
    Xe = np.linspace(0, 1, 2000)
    ue, _, se = traction_bar_exact(Xe, t)
    for ax in (ax_mpm, ax_ul):
        ax.plot(Xe + ue, se, "k-", lw=1.2, label="exact", zorder=1)
    for key, r in runs.items():
        fr = r.last()
        x = fr["x"][:, 0]
        X = x - fr["displacement"][:, 0]
        st = STYLE[key]
        ax = ax_mpm if key.startswith(("mpm", "bsmpm")) else ax_ul
        ax.plot(x, fr["stress"][:, 0], ".", ms=4, color=st["color"], label=METHODS[key][0], zorder=2)
        ue_p, _, se_p = traction_bar_exact(X, fr["time"])
        order = np.argsort(X)
        ax_u.plot(X[order], (fr["displacement"][order, 0] - ue_p[order]) * 1e6, "-", lw=1, color=st["color"],
                  label=METHODS[key][0])
        p = r.probes["end"]
        ax_v.plot(p["time"], p["v"][:, 0] * 1e3, "-", lw=1, color=st["color"], label=METHODS[key][0])
        # end-particle errors over the history
        X_end = p["x"][0, 0]
        ue_end, ve_end, _ = traction_bar_exact(np.full(len(p["time"]), X_end), p["time"])
        rows[key] = {"status": r.status, "nodes": int(r.attrs["nodes"]),
                     "end_u_max_error": float(np.abs(p["x"][:, 0] - X_end - ue_end).max()),
                     "end_u_max": float(np.abs(ue_end).max()),
                     "end_v_rms_error": float(np.sqrt(np.mean((p["v"][:, 0] - ve_end) ** 2))),
                     "history_error_end": r.error("history_error_end"),
                     "rms_displacement_error": r.error("rms_displacement_error"),
                     "rms_stress_error": r.error("rms_stress_error"),
                     "stress_max_error_X_gt_0.9": float(np.abs(fr["stress"][:, 0] - se_p)[X > 0.9].max()),
                     "wall_seconds": r.error("wall_seconds")}
    tt = np.linspace(0, t, 800)
    Xend = runs["mpm_linear"].probes["end"]["x"][0, 0]
    _, ve, _ = traction_bar_exact(np.full(tt.shape, Xend), tt)
    ax_v.plot(tt, ve * 1e3, "k-", lw=1.5, label="exact")
    ax_mpm.set(xlabel="x [m]", ylabel="sigma [Pa]", title=f"MPM variants (85 nodes): stress at t = {t:.1f} s",
               xlim=(0.5, 1.005))
    ax_ul.set(xlabel="x [m]", ylabel="sigma [Pa]", title=f"OTM / unified (68 nodes): stress at t = {t:.1f} s",
              xlim=(0.5, 1.005))
    ax_u.set(xlabel="X [m]", ylabel="u - u_exact [um]", title=f"displacement error at t = {t:.1f} s")
    ax_v.set(xlabel="t [s]", ylabel="v [mm/s]", title=f"velocity of the end particle (X = {Xend:.4f} m)")
    for ax in axes.ravel():
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, markerscale=2)
    fig.suptitle("Bar with a dynamic traction (wobbes 8.2, Fig. 7): 4 particles per cell, dt = 1e-4 s")
    fig.tight_layout()
    fig.savefig(os.path.join(FIGURES, "wobbes_traction_bar.png"), dpi=120)
    plt.close(fig)
    summary["traction_bar"] = rows

    # Stability: BSMPM with consistent mass vs unified, over total node counts.
    # xi = distance of the end particle from the grid line on its left, in
    # units of h: a B-spline degree of freedom whose support starts at that
    # line is carried by the end particle alone, with weight xi^2 / 2.
    stab = {}
    bs_cons = METHODS["bsmpm_cons"][1]
    xi_runs = {}
    for cells in range(76, 93):
        r = runner.run(f"tb_bsmpm_cons_{cells}", "traction_bar.toml", bs_cons + [f"grid.cells=[{cells}]"] + TB_FINE_OUTPUT)
        ru = runner.run(f"tb_unified_{cells}", "traction_bar.toml", METHODS["unified"][1] + [f"grid.cells=[{cells}]"])
        rl = runner.run(f"tb_bsmpm_{cells}", "traction_bar.toml", METHODS["bsmpm"][1] + [f"grid.cells=[{cells}]"])
        h = 1.25 / cells
        p = r.probes["end"]
        xi = p["x"][:, 0] / h - np.floor(p["x"][0, 0] / h)
        xi_runs[cells] = (p["time"], xi, r.status)
        stab[cells + 1] = {"bsmpm_consistent": r.status, "t_reached": float(r.attrs["t_end"]),
                           "xi_start": float(xi[0]), "xi_min": float(xi.min()),
                           "unified": ru.status, "bsmpm_lumped": rl.status}
    summary["traction_bar_stability"] = stab
    r84 = runner.run("tb_bsmpm_cons_84_fine", "traction_bar.toml", bs_cons + ["grid.cells=[84]", "output.every=0.0005"])
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.6))
    for r, lab, col in [(r84, "BSMPM consistent, 85 nodes", "tab:red"),
                        (runner.run("tb_bsmpm_cons_80", "traction_bar.toml", bs_cons + ["grid.cells=[80]"] + TB_FINE_OUTPUT,
                                    reuse=True),
                         "BSMPM consistent, 81 nodes", "tab:orange"),
                        (runs["unified"], "unified, 68 nodes", "tab:green")]:
        p = r.probes["end"]
        axes[0].plot(p["time"], p["v"][:, 0] * 1e3, lw=1, color=col, label=f"{lab}: {r.status.split(':')[0]}"
                     + (f" at t = {r.attrs['t_end']:.4f} s" if r.status != "ok" else ""))
    tt = np.linspace(0, 0.4, 800)
    _, ve, _ = traction_bar_exact(np.full(tt.shape, Xend), tt)
    axes[0].plot(tt, ve * 1e3, "k--", lw=1, label="exact")
    axes[0].set(xlabel="t [s]", ylabel="v [mm/s]", title="end-particle velocity", ylim=(-12, 2))
    for cells, (tp, xi, status) in xi_runs.items():
        if cells in (79, 80, 84, 88, 89):
            axes[1].plot(tp, xi, lw=1.2, label=f"{cells + 1} nodes: {status.split(':')[0]}")
            if status != "ok":
                axes[1].plot(tp[-1], xi[-1], "rx", ms=10)
    axes[1].set(xlabel="t [s]", ylabel="xi = (x_end - x_line) / h",
                title="BSMPM consistent: end particle's distance to the grid line on its left", ylim=(0, 1))
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Traction bar: B-spline MPM with a consistent mass matrix vs unified (wobbes 8.2)")
    fig.tight_layout()
    fig.savefig(os.path.join(FIGURES, "wobbes_traction_bar_stability.png"), dpi=120)
    plt.close(fig)


# --------------------------------------------------------------------------
# Plate with an axis-aligned manufactured displacement (wobbes 8.3)

MMS_METHODS = {
    "mpm_linear": METHODS["mpm_linear"],
    "otm_linear": METHODS["otm_linear"],
    "mpm_lme": METHODS["mpm_lme"],
    "mpm_maxent3": ("MPM-maxent (d_max 3, lumped)", MPM + LUMPED + ["basis.kind=maxent", "basis.d_max=3"]),
    "mpm_maxent3_cons": ("MPM-maxent (d_max 3, consistent)", MPM + CONSISTENT + ["basis.kind=maxent", "basis.d_max=3"]),
    "otm_maxent": METHODS["otm_maxent"],
    "bsmpm": METHODS["bsmpm"],
    "bsmpm_cons": METHODS["bsmpm_cons"],
    "unified": METHODS["unified"],
}
MMS_STYLE = dict(STYLE, mpm_maxent3=STYLE["mpm_maxent"], mpm_maxent3_cons=STYLE["mpm_maxent_cons"])
MMS_ROW = 0.07
MMS_PANELS = [("rollers", ["mpm_linear", "otm_linear", "mpm_lme"], "linear-like bases, normal components fixed"),
              ("rollers", ["mpm_maxent3", "mpm_maxent3_cons", "otm_maxent", "bsmpm", "bsmpm_cons", "unified"],
               "smooth bases, normal components fixed"),
              ("fixed", ["mpm_linear", "otm_maxent", "unified"], "all components fixed on every edge")]


def mms_plate(runner, summary):
    rows = {}
    fig, axes = plt.subplots(1, 3, figsize=(18, 5.2), sharey=True)
    for ax, (bc, keys, title) in zip(axes, MMS_PANELS):
        extra = MMS_ROLLERS if bc == "rollers" else MMS_PINNED
        first = True
        for key in keys:
            label, ov = MMS_METHODS[key]
            r = runner.run(f"mms_{bc}_{key}", "mms_plate.toml", ov + extra)
            fr = r.last()
            x = fr["x"]
            X = x - fr["displacement"]
            row_x2 = X[np.argmin(np.abs(X[:, 1] - MMS_ROW)), 1]
            m = np.abs(X[:, 1] - row_x2) < 1e-9
            order = np.argsort(X[m, 0])
            if first:
                X1 = np.linspace(0, 1, 400)
                ax.plot(X1, mms_sigma11(X1, row_x2, fr["time"]), "k-", lw=1.5, label="exact", zorder=1)
                first = False
            s11 = fr["stress"][m, 0][order]
            se = mms_sigma11(X[m, 0][order], X[m, 1][order], fr["time"])
            st = MMS_STYLE[key]
            ax.plot(x[m, 0][order], s11, st.get("linestyle", "-"), lw=0.8, marker=st["marker"], ms=3,
                    color=st["color"], label=label, zorder=2)
            se_all = mms_sigma11(X[:, 0], X[:, 1], fr["time"])
            rows[f"{bc}/{key}"] = {"status": r.status, "rms_stress_error": r.error("rms_stress_error"),
                                   "rms_displacement_error": r.error("rms_displacement_error"),
                                   "row_X2": float(row_x2),
                                   "row_max_sigma11_error": float(np.abs(s11 - se).max()),
                                   "sigma11_amplitude": float(np.abs(se_all).max()),
                                   "wall_seconds": r.error("wall_seconds")}
        ax.set(xlabel="x_1 [m]")
        ax.set_title(f"{title}\nrow X_2 = {row_x2:.4f} m, t = {fr['time'] * 1e3:.1f} ms", fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    axes[0].set_ylabel("sigma_11 [Pa]")
    fig.suptitle("Plate with axis-aligned manufactured displacement (wobbes 8.3, Fig. 9): 33 x 33 nodes, 4 x 4 particles/cell")
    fig.tight_layout()
    fig.savefig(os.path.join(FIGURES, "wobbes_mms_plate.png"), dpi=120)
    plt.close(fig)
    summary["mms_plate"] = rows


# --------------------------------------------------------------------------
# Timing table (wobbes Table 1)

TIMING = [("MPM-linear", "mpm_linear"), ("OTM-linear", "otm_linear"), ("MPM-maxent", "mpm_maxent"),
          ("OTM-maxent", "otm_maxent"), ("BSMPM (consistent)", "bsmpm_cons"), ("BSMPM (lumped)", "bsmpm"),
          ("unified", "unified")]
PAPER_TABLE1 = {"OTM-linear": (1.48, 1.19), "MPM-maxent": (0.98, 2.31), "OTM-maxent": (1.55, 2.50),
                "BSMPM (consistent)": (1.32, 1.04), "unified": (1.78, 1.12)}


def timing(runner, summary, repetitions=3):
    table = {}
    for nodes in (32, 512):
        for _, key in TIMING:
            walls = []
            for rep in range(repetitions):
                r = runner.run(f"time_{key}_{nodes}_{rep}", "fixed_bar.toml",
                               METHODS[key][1] + [f"grid.cells=[{nodes - 1}]", "output.every=0"], reuse=False)
                walls.append(r.error("wall_seconds"))
            table.setdefault(key, {})[nodes] = {"walls": walls, "median": statistics.median(walls)}
    for key in table:
        for nodes in (32, 512):
            table[key][nodes]["relative"] = table[key][nodes]["median"] / table["mpm_linear"][nodes]["median"]
    summary["timing"] = table


def print_tables(summary):
    fb = summary["fixed_bar"]
    print("\n## Fixed bar: RMS displacement error [m]\n")
    print("| method | " + " | ".join(str(n) for n in fb["nodes"]) + " |")
    print("|---" * (len(fb["nodes"]) + 1) + "|")
    for key, errs in fb["rms_displacement_error"].items():
        print(f"| {METHODS[key][0]} | " + " | ".join(f"{e:.3g}" for e in errs) + " |")
    print("\nobserved order log(e1 / e2) / log(h1 / h2) between successive grids (h = 1 / cells):\n")
    print("| method | " + " | ".join(f"{a}-{b}" for a, b in zip(fb["nodes"], fb["nodes"][1:])) + " |")
    print("|---" * len(fb["nodes"]) + "|")
    for key, errs in fb["rms_displacement_error"].items():
        e = np.asarray(errs)
        h = 1.0 / (np.asarray(fb["nodes"], float) - 1)
        orders = np.log(e[:-1] / e[1:]) / np.log(h[:-1] / h[1:])
        print(f"| {METHODS[key][0]} | " + " | ".join(f"{o:.2f}" for o in orders) + " |")
    print("\n## Fixed bar stress profiles\n")
    print(json.dumps(summary["fixed_bar_stress_profile"], indent=1))
    print("\n## Traction bar\n")
    print("| method | nodes | status | max end u error [m] | end v RMS error [m/s] | RMS u error | RMS stress error | max stress error X>0.9 |")
    print("|---|---|---|---|---|---|---|---|")
    for key, r in summary["traction_bar"].items():
        print(f"| {METHODS[key][0]} | {r['nodes']} | {r['status']} | {r['end_u_max_error']:.3g} | {r['end_v_rms_error']:.3g} | "
              f"{r['rms_displacement_error']:.3g} | {r['rms_stress_error']:.3g} | {r['stress_max_error_X_gt_0.9']:.3g} |")
    print("\n| nodes in all | BSMPM consistent | t reached [s] | xi at t = 0 | xi min | BSMPM lumped | unified |")
    print("|---|---|---|---|---|---|---|")
    for n, r in summary["traction_bar_stability"].items():
        print(f"| {n} | {r['bsmpm_consistent'].split(',')[0]} | {r['t_reached']:.4g} | {r['xi_start']:.3f} | "
              f"{r['xi_min']:.3f} | {r['bsmpm_lumped']} | {r['unified']} |")
    print("\n## MMS plate\n")
    print("| BC / method | status | RMS stress error [Pa] | RMS u error [m] | row X2 | max sigma11 error on row [Pa] | sigma11 amplitude [Pa] |")
    print("|---|---|---|---|---|---|---|")
    for key, r in summary["mms_plate"].items():
        bc, m = key.split("/")
        print(f"| {bc} / {MMS_METHODS[m][0]} | {r['status']} | {r['rms_stress_error']:.3g} | {r['rms_displacement_error']:.3g} | "
              f"{r['row_X2']:.4f} | {r['row_max_sigma11_error']:.3g} | {r['sigma11_amplitude']:.4g} |")
    if "timing" in summary:
        print("\n## Timing (fixed bar, OMP_NUM_THREADS=1, median of 3, relative to MPM-linear)\n")
        print("| method | 32 nodes | 512 nodes | paper 32 | paper 512 | median wall 32 [s] | median wall 512 [s] |")
        print("|---|---|---|---|---|---|---|")
        for name, key in TIMING:
            t = summary["timing"][key]
            p = PAPER_TABLE1.get(name, ("-", "-"))
            print(f"| {name} | {t[32]['relative']:.2f} | {t[512]['relative']:.2f} | {p[0]} | {p[1]} | "
                  f"{t[32]['median']:.4f} | {t[512]['median']:.4f} |")


def find_otmpm():
    for pattern in ["build/bin/otmpm", "build-*/bin/otmpm"]:
        hits = sorted(glob.glob(os.path.join(ROOT, pattern)))
        if hits:
            return hits[0]
    return "otmpm"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--otmpm", default=os.environ.get("OTMPM") or find_otmpm(), help="the otmpm executable")
    ap.add_argument("--work", default="/tmp/wobbes_figures", help="directory for the result files")
    ap.add_argument("--reuse", action="store_true", help="reuse existing result files (not for timings)")
    ap.add_argument("--no-timing", action="store_true", help="skip the timing table")
    args = ap.parse_args()
    print(f"otmpm: {args.otmpm}")
    runner = Runner(args.otmpm, args.work, args.reuse)
    os.makedirs(FIGURES, exist_ok=True)
    summary = {}
    fixed_bar(runner, summary)
    traction_bar(runner, summary)
    mms_plate(runner, summary)
    if not args.no_timing:
        timing(runner, summary)
    with open(os.path.join(args.work, "summary.json"), "w") as f:
        json.dump(summary, f, indent=1, default=str)
    print_tables(summary)


if __name__ == "__main__":
    main()
