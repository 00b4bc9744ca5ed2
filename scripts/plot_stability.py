#!/usr/bin/python3
"""Stability map and largest-stable-cfl table of an `otmpm study` CSV with a
[stability] section (see drivers/study_command.cpp).

    /usr/bin/python3 scripts/plot_stability.py STUDY.csv [--band 0.05] [--key simulation.cfl]
        [--out PREFIX] [--title TEXT] [--mesh NAME]

One row of the map per combination (the variant without the swept value, e.g.
"mpm-linear-fe"), one column per value of KEY. Colours: stable (exit 0 and
max_energy_ratio <= 1 + band), energy growth (finished, but with more energy
than the band allows), blown up (exit 1: NaN, runaway energy, det F <= 0, ...),
refused (exit 2). Each cell shows max_energy_ratio. The largest stable value
of each row (it and every smaller value of the grid stable) is framed.

Writes PREFIX.png and PREFIX.svg (default: the CSV path without .csv, plus
"_map") and prints the markdown table of the largest stable value per
combination on stdout.
"""
import argparse
import csv
import math
import sys
from collections import OrderedDict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Patch, Rectangle  # noqa: E402

COLOURS = OrderedDict(
    [
        ("stable", ("#4daf4a", "stable")),
        ("energy_growth", ("#ff9f1c", "energy growth > band")),
        ("blown_up", ("#d7191c", "blown up (exit 1)")),
        ("refused", ("#9e9e9e", "refused (exit 2)")),
        ("failed", ("#222222", "failed")),
    ]
)


def number(text):
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def classify(row, band):
    """The stability class: the CSV's own column, or computed from exit code and energy ratio."""
    if row.get("stability"):
        return row["stability"]
    code = row.get("exit_code", "")
    if code == "0":
        ratio = number(row.get("max_energy_ratio"))
        if math.isnan(ratio):
            return "failed"
        return "stable" if ratio <= 1.0 + band else "energy_growth"
    return {"1": "blown_up", "2": "refused"}.get(code, "failed")


def combination(row, key):
    """The variant name without the segment holding the swept value (the last one equal to it)."""
    parts = row["variant"].split("/")
    value = row[key]
    for i in range(len(parts) - 1, -1, -1):
        if parts[i] == value:
            del parts[i]
            break
    return "/".join(parts) or "base"


def load(path, key, band, mesh):
    """{combination: {value: (class, max_energy_ratio, row)}} in the order of the CSV.
    With several meshes in the CSV (and no --mesh), the combination names end in "@ mesh"."""
    with open(path, newline="") as f:
        rows = [row for row in csv.DictReader(f) if not mesh or row["mesh"] == mesh]
    if rows and key not in rows[0]:
        sys.exit(f"{path}: no column '{key}' (is it swept?)")
    several = len({row["mesh"] for row in rows}) > 1
    table = OrderedDict()
    for row in rows:
        name = combination(row, key) + (f" @ {row['mesh']}" if several else "")
        table.setdefault(name, {})[number(row[key])] = (classify(row, band), number(row.get("max_energy_ratio")), row)
    return table


def largest_stable(cells):
    """The largest value v with v and every smaller value of the grid stable (None if the smallest is not)."""
    best = None
    for value in sorted(cells):
        if cells[value][0] != "stable":
            break
        best = value
    return best


def first_unstable(cells):
    for value in sorted(cells):
        if cells[value][0] != "stable":
            return value, cells[value][0]
    return None, None


def fmt(value):
    return "-" if value is None else f"{value:g}"


def markdown(table, key, band):
    lines = [
        f"| combination | largest stable {key} | first {key} not stable (class) | max_energy_ratio at the largest stable |",
        "|---|---|---|---|",
    ]
    for name, cells in table.items():
        best = largest_stable(cells)
        bad, cls = first_unstable(cells)
        grid_max = max(cells)
        ratio = cells[best][1] if best is not None else math.nan
        best_text = fmt(best) if bad is not None or best is None else f">= {fmt(best)} (all stable up to {fmt(grid_max)})"
        bad_text = f"{fmt(bad)} ({cls})" if bad is not None else "none"
        ratio_text = "-" if math.isnan(ratio) else f"{ratio:.4f}"
        lines.append(f"| {name} | {best_text} | {bad_text} | {ratio_text} |")
    lines.append("")
    lines.append(f"stable: exit 0 and max_energy_ratio <= 1 + {band:g}")
    return "\n".join(lines)


def draw(table, key, band, title, prefix):
    values = sorted({v for cells in table.values() for v in cells})
    names = list(table)
    fig, ax = plt.subplots(figsize=(1.0 + 0.62 * len(values) + 2.2, 1.2 + 0.42 * len(names)))
    for y, name in enumerate(names):
        cells = table[name]
        best = largest_stable(cells)
        for x, value in enumerate(values):
            if value not in cells:
                continue
            cls, ratio, _ = cells[value]
            colour = COLOURS.get(cls, COLOURS["failed"])[0]
            ax.add_patch(Rectangle((x - 0.5, y - 0.5), 1, 1, facecolor=colour, edgecolor="white", linewidth=1.5))
            if not math.isnan(ratio):
                text = f"{ratio:.2f}" if ratio < 10 else (f"{ratio:.0f}" if ratio < 1e4 else f"{ratio:.0e}")
                ax.text(x, y, text, ha="center", va="center", fontsize=6.5,
                        color="white" if cls in ("blown_up", "failed") else "black")
            if value == best:
                ax.add_patch(Rectangle((x - 0.47, y - 0.47), 0.94, 0.94, fill=False, edgecolor="black", linewidth=2.0))
    ax.set_xlim(-0.5, len(values) - 0.5)
    ax.set_ylim(len(names) - 0.5, -0.5)
    ax.set_xticks(range(len(values)))
    ax.set_xticklabels([f"{v:g}" for v in values])
    ax.set_yticks(range(len(names)))
    ax.set_yticklabels(names)
    ax.set_xlabel(key)
    ax.set_title(title or f"Stability map (band {band:g}; cell text: max_energy_ratio; frame: largest stable {key})",
                 fontsize=10)
    present = {cells[v][0] for cells in table.values() for v in cells}
    handles = [Patch(facecolor=c, label=label) for cls, (c, label) in COLOURS.items() if cls in present]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)
    fig.tight_layout()
    for ext in ("png", "svg"):
        fig.savefig(f"{prefix}.{ext}", dpi=150)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("csv")
    parser.add_argument("--band", type=float, default=0.05, help="allowed energy growth (used when the CSV has no stability column)")
    parser.add_argument("--key", default="simulation.cfl", help="the swept parameter (x axis)")
    parser.add_argument("--out", help="output prefix (default: CSV path without .csv + _map)")
    parser.add_argument("--title")
    parser.add_argument("--mesh", help="only the rows of this mesh")
    args = parser.parse_args()
    table = load(args.csv, args.key, args.band, args.mesh)
    if not table:
        sys.exit(f"{args.csv}: no rows")
    prefix = args.out or (args.csv[:-4] if args.csv.endswith(".csv") else args.csv) + "_map"
    draw(table, args.key, args.band, args.title, prefix)
    print(markdown(table, args.key, args.band))
    print(f"wrote {prefix}.png and {prefix}.svg")


if __name__ == "__main__":
    main()
