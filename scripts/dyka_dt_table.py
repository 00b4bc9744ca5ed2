#!/usr/bin/env python3
"""Tables of the Dyka time-step refinement study (examples/studies/dyka_dt.toml).

Reads the study CSV and, from the result files of the study's results folder,
the /energy series, and prints for each mesh size a markdown table: per basis
and integrator, for each cfl, the RMS velocity error at t_end, the history
error of point A and the energy lost by t_end,

    loss = -(E(t_end) - E(0) - W(t_end)) / E(0),   E = kinetic + strain,
    W = external work + reaction work (zero for the Dyka bar),

in per cent of E(0) (positive: the scheme dissipated energy), and a table of
wall times. Usage:

    /usr/bin/python3 scripts/dyka_dt_table.py docs/data/studies/dyka_dt.csv [--results DIR]
"""
import argparse
import csv
import os
import re

import h5py


def energy_loss(path):
    """-(E(t_end) - E(0) - W(t_end)) / E(0) from the /energy series of a result file."""
    with h5py.File(path, "r") as f:
        g = f["energy"]
        e = g["kinetic"][:] + g["strain"][:]
        w = g["external_work"][:] + g["reaction_work"][:]
        return -(e[-1] - e[0] - w[-1]) / e[0], float(g["time"][-1])


def safe_name(s):
    """The study runner's file name of a run (drivers/study_command.cpp, safe_name)."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", s)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("csv")
    ap.add_argument("--results", help="folder of the result files (default: CSV stem + _results)")
    a = ap.parse_args()
    results = a.results or os.path.join(os.path.dirname(a.csv), os.path.splitext(os.path.basename(a.csv))[0] + "_results")
    with open(a.csv) as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        path = os.path.join(results, safe_name(r["variant"] + "_" + r["mesh"]) + ".h5")
        r["loss"], r["t_last"] = energy_loss(path) if os.path.exists(path) else (float("nan"), float("nan"))
    cfls = sorted({float(r["simulation.cfl"]) for r in rows}, reverse=True)
    meshes = list(dict.fromkeys(r["mesh"] for r in rows))
    combos = list(dict.fromkeys((r["basis.kind"], r["simulation.integrator"]) for r in rows))
    pick = {(r["mesh"], r["basis.kind"], r["simulation.integrator"], float(r["simulation.cfl"])): r for r in rows}
    for mesh in meshes:
        print_table(f"### {mesh}: RMS velocity error at t_end / history error A [m/s] / "
                    "energy lost by t_end [% of E(0)]", combos, cfls,
                    lambda b, i, c: error_cell(pick.get((mesh, b, i, c))))
        print_table(f"{mesh}: steps / wall time [s]", combos, cfls,
                    lambda b, i, c: time_cell(pick.get((mesh, b, i, c))))


def error_cell(r):
    if r is None or r["status"] != "ok":
        return r["status"] if r else "-"
    return f"{float(r['rms_velocity_error']):.4f} / {float(r['history_error']):.4f} / {100 * r['loss']:.2f}"


def time_cell(r):
    return f"{r['steps']} / {float(r['wall_seconds']):.2f}" if r else "-"


def print_table(title, combos, cfls, cell):
    """A markdown table: one row per (basis, integrator), one column per cfl."""
    print(f"\n{title}\n")
    print("| basis, integrator | " + " | ".join(f"cfl {c:g}" for c in cfls) + " |")
    print("|---|" + "---|" * len(cfls))
    for b, i in combos:
        print(f"| {b}, {i} | " + " | ".join(cell(b, i, c) for c in cfls) + " |")

if __name__ == "__main__":
    main()
