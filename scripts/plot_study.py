#!/usr/bin/python3
"""Work-precision and convergence plots of an `otmpm study` CSV.

    /usr/bin/python3 scripts/plot_study.py STUDY.csv [--error rms_velocity_error] [--out PREFIX]
        [--variants REGEX] [--title TEXT] [--table] [--order COLUMN] [--estimate COLUMN]

Writes PREFIX_work_precision.{png,svg} (error against wall time, log-log, one
line per variant through its mesh sizes) and PREFIX_convergence.{png,svg}
(error against h); neither when no run has a value in the error column (a
scene without an exact solution) and none failed, and it says so. Runs that did not finish ok (unstable, refused) are drawn as
red crosses at the top of the axes, at their wall time / h, not left out.
With --table it also prints a markdown table on stdout: one row per variant,
one column per mesh, each cell "error / wall time" (or the status of a run
that did not finish ok). With --order COLUMN (an errors CSV of
otmpm.convergence: the observed order) each variant's label gives its
observed order between its two finest runs; with --estimate COLUMN a dashed
line of the variant's colour draws that column too (the Richardson error
estimate |q - q_Richardson|).
"""
import argparse
import csv
import math
import re
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def number(text):
    try:
        value = float(text)
    except (TypeError, ValueError):
        return math.nan
    return value


def load(path, error, pattern, order=None, estimate=None):
    series = defaultdict(list)
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            if pattern and not re.search(pattern, row["variant"]):
                continue
            series[row["variant"]].append(
                {
                    "h": number(row["h"]),
                    "wall": number(row["wall_seconds"]),
                    "error": number(row.get(error)),
                    "ok": row["status"] == "ok",
                    "mesh": row["mesh"],
                    "status": row["status"],
                    "order": number(row.get(order)) if order else math.nan,
                    "estimate": number(row.get(estimate)) if estimate else math.nan,
                }
            )
    for runs in series.values():
        runs.sort(key=lambda r: -r["h"])
    return series


def draw(series, xkey, xlabel, error, title, prefix, suffix):
    fig, ax = plt.subplots(figsize=(8.5, 6))
    finite = [r["error"] for runs in series.values() for r in runs if r["ok"] and r["error"] > 0]
    top = max(finite) * 3 if finite else 1.0
    markers = "osD^v<>phX*"
    bad_labelled = False
    estimate_labelled = False
    for i, (variant, runs) in enumerate(sorted(series.items())):
        good = [r for r in runs if r["ok"] and r["error"] > 0 and r[xkey] > 0]
        orders = [r["order"] for r in good if math.isfinite(r["order"])]
        label = variant + (f" (observed order {orders[-1]:.2f})" if orders else "")
        line = ax.loglog([r[xkey] for r in good], [r["error"] for r in good], marker=markers[i % len(markers)],
                         ms=4, lw=1.2, label=label, color=plt.cm.tab20(i % 20))[0]
        rich = [r for r in runs if r["ok"] and r["estimate"] > 0 and r[xkey] > 0]
        if rich:
            ax.loglog([r[xkey] for r in rich], [r["estimate"] for r in rich], ls="--", lw=1, color=line.get_color(),
                      label=None if estimate_labelled else "dashed: Richardson estimate of the error")
            estimate_labelled = True
        bad = [r for r in runs if not r["ok"] and r[xkey] > 0]
        if bad:
            ax.loglog([r[xkey] for r in bad], [top] * len(bad), "x", color="red", ms=9, mew=2,
                      label=None if bad_labelled else "not ok (unstable / refused)")
            ax.loglog([r[xkey] for r in bad], [top] * len(bad), marker=markers[i % len(markers)], ls="none",
                      mfc="none", color=line.get_color(), ms=5)
            bad_labelled = True
    ax.set_xlabel(xlabel)
    ax.set_ylabel(error.replace("_", " "))
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2, loc="best")
    fig.tight_layout()
    for ext in ("png", "svg"):
        fig.savefig(f"{prefix}_{suffix}.{ext}", dpi=130)
    plt.close(fig)
    print(f"wrote {prefix}_{suffix}.png and .svg")


def print_table(series):
    """Markdown table: variants down, meshes (coarse to fine) across, "error / wall s" per cell."""
    meshes = list(dict.fromkeys(r["mesh"] for runs in series.values() for r in runs))
    print("| variant | " + " | ".join(meshes) + " |")
    print("|---|" + "---|" * len(meshes))
    for variant, runs in sorted(series.items()):
        by_mesh = {r["mesh"]: r for r in runs}
        cells = []
        for m in meshes:
            r = by_mesh.get(m)
            if r is None:
                cells.append("-")
            elif r["ok"]:
                cells.append(f"{r['error']:.3f} / {r['wall']:.2f} s")
            else:
                cells.append(r["status"].split(":")[0] + f" ({r['wall']:.2f} s)")
        print(f"| {variant} | " + " | ".join(cells) + " |")


def main(argv):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("csv")
    p.add_argument("--error", default="rms_velocity_error")
    p.add_argument("--out", default=None, help="output prefix (default: the CSV path without .csv)")
    p.add_argument("--variants", default=None, help="regular expression selecting variants")
    p.add_argument("--title", default=None)
    p.add_argument("--table", action="store_true", help="print the markdown table of error / wall time")
    p.add_argument("--order", default=None, help="column of the observed order (shown in the legend)")
    p.add_argument("--estimate", default=None, help="column of an error estimate (dashed lines)")
    a = p.parse_args(argv)
    prefix = a.out or re.sub(r"\.csv$", "", a.csv)
    series = load(a.csv, a.error, a.variants, a.order, a.estimate)
    if not series:
        sys.exit(f"{a.csv}: no rows")
    runs = [r for rs in series.values() for r in rs]
    if all(r["ok"] and not math.isfinite(r["error"]) for r in runs):
        # Empty axes would say nothing: a scene without an exact solution.
        print(f"{a.csv}: no run has a value in column {a.error} (the scene has no exact solution to compare "
              "with): no plots drawn; a [[measure]] in the study gives errors against a reference run")
        return
    title = a.title or a.csv
    draw(series, "wall", "wall time [s] (one core per run)", a.error, title + ": work-precision", prefix,
         "work_precision")
    draw(series, "h", "mesh size h [m]", a.error, title + ": convergence", prefix, "convergence")
    if a.table:
        print_table(series)


if __name__ == "__main__":
    main(sys.argv[1:])
