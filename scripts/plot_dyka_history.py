#!/usr/bin/python3
"""Dyka bar: velocity history of point A, molinos Fig. 7 style.

1. Runs examples/dyka/dyka_n133.toml (h = L/133, LME gamma_lme = 4, mpm) with
   the forward Euler (fe) and the Newmark predictor-corrector (npc)
   integrators, with frames (and so probe samples) every 0.1 us
   (--set output.every=1e-7: the ringing after each jump has a period of
   about 1.5 us, which the scene's 1 us frames would alias), reads the probe A
   history from the result files and plots it against the exact
   (characteristics) solution:
       docs/figures/dyka_history_n133.png
   It also runs both integrators on the scene exactly as shipped (frames
   every 1 us) and with gamma_lme = 2.8 (about the paper's gamma = 4, see
   docs/benchmarks.md), and prints markdown tables of the errors, wall time and
   steps, and of the ringing after each jump.
2. Runs the same bar at h = L/40 in 1D (examples/dyka/dyka_n40.toml), 2D
   (examples/dyka_2d.toml) and 3D (examples/dyka_3d.toml) with npc, frames
   every 0.1 us, and plots the three point-A histories on top of each other:
       docs/figures/dyka_dimensions.png
3. With --sweep: fe and npc at the seven mesh sizes of the paper
   (examples/dyka/dyka_nN.toml as shipped), molinos Fig. 6 style:
       docs/figures/dyka_convergence.png

    /usr/bin/python3 scripts/plot_dyka_history.py --otmpm build/bin/otmpm [--sweep]
    /usr/bin/python3 scripts/plot_dyka_history.py --work-dir /tmp/dyka --no-run   # re-plot

Wall times are whatever the machine gave; set OMP_NUM_THREADS=1 on a busy
machine (OpenMP threads that spin while the cores are taken make the wall
time vary by an order of magnitude).

The exact solution is written here independently of the C++ one
(lib/otmpm/reference/), so the figure also cross-checks it: c = sqrt(E/rho),
V the initial velocity extended evenly about x = 0 and oddly about x = L
(period 4L), v(X, t) = (V(X - ct) + V(X + ct)) / 2 at the probe's initial
position X (its first x sample).
"""
import argparse
import math
import os
import subprocess
import sys
import tempfile
import tomllib

import matplotlib

matplotlib.use("Agg")
import h5py  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

# Dyka bar (docs/benchmarks.md, molinos sect. 3.1)
L = 0.1333         # bar length [m]
RHO = 7833.0       # density [kg/m3]
E = 200.0e9        # Young's modulus [Pa]
V0 = -5.0          # initial velocity of the left quarter [m/s]
X_V0 = L / 4.0     # the left quarter [0, L/4] moves
C = math.sqrt(E / RHO)
EXACT_SAMPLES = 20001  # resolves the jumps of the exact history on the plot
# Probe sampling for the figures: 5 steps per sample at h = L/133, cfl = 0.1.
FINE_EVERY = 1.0e-7
ZOOMS_US = ((3.0, 26.0), (56.0, 79.0))  # after the first two jumps at point A
# Windows after a jump (us): from the first overshoots (after the smeared jump itself), then what is left.
OSC_WINDOWS_US = ((2.0, 10.0), (10.0, 20.0))

PROBE = "A"
HISTORY_MESH = 133                               # h = L/133 = 1 mm, molinos Fig. 7
PAPER_MESHES = (13, 20, 40, 133, 267, 401, 1333)  # examples/dyka/dyka_nN.toml
# The paper's gamma = 4 is about 0.7 * 4 in beta = gamma_lme / h^2 (docs/benchmarks.md).
PAPER_GAMMA_LME = 2.8
INTEGRATORS = ("fe", "npc")
LABELS = {"fe": "FE (forward Euler)", "npc": "NPC (Newmark predictor-corrector)"}
COLOURS = {"fe": "C3", "npc": "C0", "1D": "C0", "2D": "C1", "3D": "C2"}


# ---------------------------------------------------------------- exact solution

def initial_velocity(x):
    """V on [0, L]: V0 on the left quarter, 0 elsewhere."""
    return np.where((x >= 0.0) & (x <= X_V0), V0, 0.0)


def extended_velocity(x):
    """V extended evenly about x = 0 and oddly about x = L, period 4L."""
    y = np.mod(np.asarray(x, dtype=float) + L, 4.0 * L) - L  # y in [-L, 3L)
    return np.where(y <= L, initial_velocity(np.abs(y)), -initial_velocity(np.abs(2.0 * L - y)))


def exact_velocity(X, t):
    """d'Alembert: v(X, t) = (V(X - ct) + V(X + ct)) / 2."""
    return 0.5 * (extended_velocity(X - C * t) + extended_velocity(X + C * t))


def self_check():
    """Properties the exact solution must have; a wrong formula would make a wrong figure."""
    t = np.linspace(0.0, 1e-4, 101)
    assert np.allclose(exact_velocity(L, t), 0.0), "v(L, t) must vanish (fixed end)"
    assert np.isclose(exact_velocity(0.01, 0.0), V0) and np.isclose(exact_velocity(0.05, 0.0), 0.0)
    # The free end keeps V0 until the unloading wave from x = L/4 arrives at t = L/(4c).
    assert np.isclose(exact_velocity(0.0, 0.9 * X_V0 / C), V0)
    assert np.isclose(exact_velocity(0.0, 1.1 * X_V0 / C), 0.0)
    # Period of the whole motion: 4L/c.
    assert np.allclose(exact_velocity(0.02, t), exact_velocity(0.02, t + 4.0 * L / C))


# ---------------------------------------------------------------- running otmpm

def run(otmpm, scene, out, sets=()):
    """Runs one scene; returns the exit status (0 ok, 1 unstable - the file is still valid)."""
    cmd = [otmpm, "run", scene, "--quiet", "--out", out]
    for s in sets:
        cmd += ["--set", s]
    print("$ " + " ".join(cmd), flush=True)
    res = subprocess.run(cmd, capture_output=True, text=True)
    print(res.stdout.strip(), flush=True)
    if res.returncode not in (0, 1):
        sys.exit(f"plot_dyka_history: otmpm failed with status {res.returncode}:\n{res.stderr}")
    if res.returncode == 1:
        print(f"(unstable) {res.stderr.strip()}", flush=True)
    return res.returncode


def text_attr(v):
    return v.decode() if isinstance(v, bytes) else str(v)


def read_result(path):
    """Root attributes and the probe A history (time, X = first x sample, v_x)."""
    with h5py.File(path, "r") as f:
        attrs = {k: (text_attr(v) if isinstance(v, (bytes, str)) else float(v)) for k, v in f.attrs.items()}
        g = f["probes"][PROBE]
        t = g["time"][:]
        x = g["x"][:]
        v = g["v"][:]
    every = tomllib.loads(attrs["scene"]).get("output", {}).get("every", 0.0)
    return {"attrs": attrs, "t": t, "X": float(x[0, 0]), "v": v[:, 0], "path": path, "every": every}


# ---------------------------------------------------------------- figures

def fmt_attr(r, key, spec):
    v = r["attrs"].get(key)
    return "-" if v is None else format(v, spec)


def history_figure(results, n, path):
    fig = plt.figure(figsize=(12, 9.2), constrained_layout=True)
    gs = fig.add_gridspec(2, 2, height_ratios=[1.35, 1.0])
    ax = fig.add_subplot(gs[0, :])
    zooms = [fig.add_subplot(gs[1, k]) for k in range(2)]
    X = results["npc"]["X"]
    t_end = max(r["t"][-1] for r in results.values())
    te = np.linspace(0.0, t_end, EXACT_SAMPLES)
    for a in [ax, *zooms]:
        a.plot(te * 1e6, exact_velocity(X, te), color="k", lw=1.6, label="exact (characteristics)", zorder=3)
        for name, r in results.items():
            a.plot(r["t"] * 1e6, r["v"], color=COLOURS[name], lw=1.1, alpha=0.9,
                   label=history_label(name, r))
        a.grid(True, color="0.9")
        a.set_xlabel("time [$\\mu$s]")
        a.set_ylabel("velocity of point A [m/s]")
    ax.set_xlim(0.0, t_end * 1e6)
    ax.set_ylim(-6.5, 6.5)
    for a, (t0, t1) in zip(zooms, ZOOMS_US):
        a.set_xlim(t0, t1)
        a.set_ylim(-2.0, 2.0)
        a.set_title(f"zoom: {t0:g} to {t1:g} $\\mu$s", fontsize=10)
        ax.axvspan(t0, t1, color="0.5", alpha=0.08, lw=0)
    ax.legend(loc="lower center", fontsize=8.5, framealpha=0.95, title_fontsize=7.5,
              title="wall times: shared, busy 2-core machine, indicative only (careful timings: docs/performance.md)")
    dt_probe = results["npc"]["every"] * 1e6
    ax.set_title(f"Dyka bar, h = L/{n} = {L / n * 1e3:.3g} mm, mpm, LME $\\gamma_{{lme}}$ = 4, cfl = 0.1: velocity of "
                 f"point A (X = {X * 1e3:.4f} mm), frames every {dt_probe:g} $\\mu$s  (cf. molinos et al. Fig. 7)",
                 fontsize=10.5)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote {path}")


def history_label(name, r):
    a = r["attrs"]
    status = "" if a.get("status", "ok") == "ok" else "  [" + a["status"] + "]"
    return (f"{LABELS[name]}: RMS v error at t_end {fmt_attr(r, 'rms_velocity_error', '.4f')} m/s, "
            f"history error A {fmt_attr(r, 'history_error_' + PROBE, '.4f')} m/s, "
            f"wall {fmt_attr(r, 'wall_seconds', '.1f')} s{status}")


def on_common_time(ref, other):
    """other's v at ref's probe times (linear interpolation; identical when the steps agree)."""
    if len(ref["t"]) == len(other["t"]) and np.allclose(ref["t"], other["t"], rtol=0, atol=1e-12):
        return other["v"]
    return np.interp(ref["t"], other["t"], other["v"])


def dimensions_figure(results, n, path):
    fig, (ax, axd) = plt.subplots(2, 1, figsize=(11, 7.5), constrained_layout=True, sharex=True,
                                  gridspec_kw={"height_ratios": [3, 1.3]})
    ref = results["1D"]
    t_end = max(r["t"][-1] for r in results.values())
    te = np.linspace(0.0, t_end, EXACT_SAMPLES)
    ax.plot(te * 1e6, exact_velocity(ref["X"], te), color="k", lw=1.4, label="exact", zorder=1)
    styles = {"1D": ("-", 3.2), "2D": ("--", 2.0), "3D": (":", 2.0)}
    for name, r in results.items():
        ls, lw = styles[name]
        label = (f"{name}: {int(r['attrs']['particles'])} particles, history error A "
                 f"{fmt_attr(r, 'history_error_' + PROBE, '.4f')} m/s, wall {fmt_attr(r, 'wall_seconds', '.1f')} s")
        ax.plot(r["t"] * 1e6, r["v"], ls, color=COLOURS[name], lw=lw, label=label, zorder=2)
        if name != "1D":
            d = on_common_time(ref, r) - ref["v"]
            axd.plot(ref["t"] * 1e6, d, ls, color=COLOURS[name], lw=1.4,
                     label=f"{name} - 1D (max |diff| = {np.max(np.abs(d)):.2e} m/s)")
    ax.set_ylabel("velocity of point A [m/s]")
    ax.set_ylim(-6.5, 6.5)
    ax.grid(True, color="0.9")
    ax.legend(loc="upper left", fontsize=8.5, framealpha=0.95, title_fontsize=7.5,
              title="wall times: shared, busy machine, indicative only")
    ax.set_title(f"Dyka bar in 1D, 2D (one row of cells, 2x2 ppc) and 3D (2x2x2 ppc), h = L/{n}, "
                 f"mpm, LME $\\gamma_{{lme}}$ = 4, NPC: point A, frames every {ref['every'] * 1e6:g} $\\mu$s", fontsize=10.5)
    axd.set_xlabel("time [$\\mu$s]")
    axd.set_ylabel("difference [m/s]")
    axd.set_xlim(0.0, t_end * 1e6)
    axd.grid(True, color="0.9")
    axd.legend(loc="upper left", fontsize=8.5, framealpha=0.95)
    axd.ticklabel_format(axis="y", style="sci", scilimits=(-2, 2))
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote {path}")


# ---------------------------------------------------------------- tables

def table(rows, header):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for label, r in rows:
        a = r["attrs"]
        lines.append(f"| {label} | {r['every'] * 1e6:g} | {a.get('status', '?')} | {fmt_attr(r, 'rms_velocity_error', '.4f')} | "
                     f"{fmt_attr(r, 'history_error_' + PROBE, '.4f')} | {fmt_attr(r, 'wall_seconds', '.2f')} | "
                     f"{int(a['steps'])} | {int(a['particles'])} |")
    return "\n".join(lines)


def jump_times(X, t_end):
    """Times at which the exact history of X jumps to 0 and then stays 0 for OSC_WINDOWS_US[-1][1]."""
    te = np.linspace(0.0, t_end, 40 * EXACT_SAMPLES)
    ve = exact_velocity(X, te)
    idx = np.nonzero(np.abs(np.diff(ve)) > 0.1 * abs(V0))[0]
    out = []
    for i in idx:
        t = te[i + 1]
        if out and t - out[-1] < 1e-6:
            continue  # the half-value sample at the jump itself
        after = (te > t + 1e-8) & (te < t + OSC_WINDOWS_US[-1][1] * 1e-6)
        if t + OSC_WINDOWS_US[-1][1] * 1e-6 <= t_end and np.all(ve[after] == 0.0):
            out.append(t)
    return out


def oscillation_table(results):
    """max |v_A - v_exact| in windows after each jump to zero: how fast the ringing dies out."""
    X = results["npc"]["X"]
    t_end = min(r["t"][-1] for r in results.values())
    head = ["run", "jump at [us]"] + [f"max abs error, jump + {a:g} to {b:g} us [m/s]" for a, b in OSC_WINDOWS_US]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for tj in jump_times(X, t_end):
        for name, r in results.items():
            err = np.abs(r["v"] - exact_velocity(X, r["t"]))
            cells = []
            for a, b in OSC_WINDOWS_US:
                w = (r["t"] >= tj + a * 1e-6) & (r["t"] <= tj + b * 1e-6)
                cells.append(f"{err[w].max():.3f}")
            lines.append(f"| {name.upper()} | {tj * 1e6:.2f} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


HEADER = ["run", "frames every [us]", "status", "RMS velocity error at t_end [m/s]", "history error A [m/s]", "wall time [s]",
          "steps", "particles"]


def scene_path(n):
    return os.path.join(ROOT, "examples", "dyka", f"dyka_n{n}.toml")


def study_history(a, work):
    """FE vs NPC at h = L/133: figure (fine frames), table, ringing table."""
    n = HISTORY_MESH
    hist, shipped, paper_gamma = {}, {}, {}
    for integ in INTEGRATORS:
        out = os.path.join(work, f"dyka_n{n}_{integ}_fine.h5")
        if not a.no_run:
            run(a.otmpm, scene_path(n), out, [f"simulation.integrator={integ}", f"output.every={FINE_EVERY!r}"])
        hist[integ] = read_result(out)
    history_figure(hist, n, os.path.join(a.out_dir, f"dyka_history_n{n}.png"))
    for integ in INTEGRATORS:
        out = os.path.join(work, f"dyka_n{n}_{integ}.h5")
        if not a.no_run:
            run(a.otmpm, scene_path(n), out, [f"simulation.integrator={integ}"])
        shipped[integ] = read_result(out)
    for integ in INTEGRATORS:
        out = os.path.join(work, f"dyka_n{n}_{integ}_gamma{PAPER_GAMMA_LME:g}.h5")
        if not a.no_run:
            run(a.otmpm, scene_path(n), out, [f"simulation.integrator={integ}", f"basis.gamma_lme={PAPER_GAMMA_LME!r}"])
        paper_gamma[integ] = read_result(out)
    print(f"\nDyka bar, h = L/{n}, mpm, LME, cfl = 0.1, t_end = 1e-4 s:\n")
    rows = [(k.upper() + ", gamma_lme 4 (figure)", r) for k, r in hist.items()]
    rows += [(k.upper() + ", gamma_lme 4 (scene as shipped)", r) for k, r in shipped.items()]
    rows += [(k.upper() + f", gamma_lme {PAPER_GAMMA_LME:g} (~ paper's 4)", r) for k, r in paper_gamma.items()]
    print(table(rows, HEADER))
    print(f"\nRinging after the jumps of point A to v = 0 (frames every {FINE_EVERY * 1e6:g} us):\n")
    print(oscillation_table(hist))


def study_dimensions(a, work):
    """The same bar at h = L/40 in 1D, 2D and 3D: the point-A histories must agree."""
    n = 40
    scenes = {"1D": scene_path(n),
              "2D": os.path.join(ROOT, "examples", "dyka_2d.toml"),
              "3D": os.path.join(ROOT, "examples", "dyka_3d.toml")}
    dims = {}
    for name, sc in scenes.items():
        out = os.path.join(work, f"dyka_n{n}_{name}.h5")
        if not a.no_run:
            run(a.otmpm, sc, out, ["simulation.integrator=npc", f"output.every={FINE_EVERY!r}"])
        dims[name] = read_result(out)
    dimensions_figure(dims, n, os.path.join(a.out_dir, "dyka_dimensions.png"))
    print(f"\nDyka bar, h = L/{n}, mpm, LME gamma_lme = 4, NPC, in 1D/2D/3D:\n")
    print(table(list(dims.items()), HEADER))


def convergence_figure(sweep, path):
    fig, axes = plt.subplots(1, 2, figsize=(12, 5), constrained_layout=True)
    for ax, key, what in ((axes[0], "rms_velocity_error", "RMS velocity error at $t_{end}$"),
                          (axes[1], "history_error_" + PROBE, "history error of point A")):
        for integ in INTEGRATORS:
            pts = [(L / n * 1e3, r["attrs"].get(key)) for n, r in sweep[integ].items()]
            pts = [(h, e) for h, e in pts if e is not None]
            ax.loglog(*zip(*pts), "o-", color=COLOURS[integ], label=LABELS[integ])
        ax.set_xlabel("h [mm]")
        ax.set_ylabel(f"{what} [m/s]")
        ax.grid(True, which="both", color="0.9")
        ax.legend(fontsize=9)
    axes[1].set_title("RMS over the frames: every 1 $\\mu$s, every 2 $\\mu$s for h = L/401 and L/1333",
                      fontsize=9)
    fig.suptitle("Dyka bar, mpm, LME $\\gamma_{lme}$ = 4, cfl = 0.1, t_end = 1e-4 s, scenes examples/dyka/dyka_nN.toml "
                 "(cf. molinos et al. Fig. 6)", fontsize=10.5)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote {path}")


def study_sweep(a, work):
    """FE and NPC at the seven mesh sizes of the paper (molinos Fig. 6)."""
    sweep = {integ: {} for integ in INTEGRATORS}
    for n in PAPER_MESHES:
        for integ in INTEGRATORS:
            out = os.path.join(work, f"dyka_n{n}_{integ}.h5")
            if not a.no_run and not (n == HISTORY_MESH and os.path.exists(out)):
                run(a.otmpm, scene_path(n), out, [f"simulation.integrator={integ}"])
            sweep[integ][n] = read_result(out)
    convergence_figure(sweep, os.path.join(a.out_dir, "dyka_convergence.png"))
    print("\nDyka bar, mesh sweep, mpm, LME gamma_lme = 4 (scenes as shipped):\n")
    rows = [(f"h = L/{n}, {integ.upper()}", sweep[integ][n]) for n in PAPER_MESHES for integ in INTEGRATORS]
    print(table(rows, HEADER))


def main(argv):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--otmpm", default=os.path.join(ROOT, "build", "bin", "otmpm"), help="the otmpm executable")
    p.add_argument("--work-dir", help="keep the result files here (default: a temporary directory)")
    p.add_argument("--no-run", action="store_true", help="re-plot the result files in --work-dir")
    p.add_argument("--out-dir", default=os.path.join(ROOT, "docs", "figures"))
    p.add_argument("--skip-dimensions", action="store_true", help="leave out the 1D/2D/3D comparison")
    p.add_argument("--sweep", action="store_true",
                   help="also run FE and NPC at the seven mesh sizes (minutes at h = L/1333)")
    a = p.parse_args(argv)
    if a.no_run and not a.work_dir:
        p.error("--no-run needs --work-dir")
    self_check()
    os.makedirs(a.out_dir, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        work = a.work_dir or tmp
        os.makedirs(work, exist_ok=True)
        study_history(a, work)
        if not a.skip_dimensions:
            study_dimensions(a, work)
        if a.sweep:
            study_sweep(a, work)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
