#!/usr/bin/python3
"""Energy histories of otmpm result files (the /energy series).

    /usr/bin/python3 scripts/plot_energy_histories.py LABEL=RUN.h5 ... [--right LABEL=RUN.h5 ...]
        --out FIGURE.png [--title TEXT] [--right-title TEXT] [--ymin 0.8] [--ymax 1.15] [--right-ymin Y]

Draws E(t) / (E(0) + max_t |W(t)|) against t for each run, E = kinetic +
strain energy, W = external work + reaction work: the quantity whose maximum
is the run's max_energy_ratio. Curves that leave the y range (a blow-up) are
cut at the top and marked with a cross at the time the run stopped, labelled
with its max_energy_ratio (the file's attribute, which includes the step that stopped it). --right draws a second panel (e.g. longer runs).
Prints max_energy_ratio, the ratio at the end and the status of every run.
"""
import argparse

import h5py
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def load(path):
    with h5py.File(path, "r") as f:
        e = f["energy"]
        t = e["time"][:]
        energy = e["kinetic"][:] + e["strain"][:]
        work = e["external_work"][:] + e["reaction_work"][:]
        status = f.attrs["status"]
        status = status.decode() if isinstance(status, bytes) else str(status)
        ratio_attr = float(f.attrs.get("max_energy_ratio", np.nan))
    reference = energy[0] + np.max(np.abs(work))
    return t, energy / reference, status, ratio_attr


def panel(ax, runs, title, ymin, ymax, colours):
    marked = 0
    for i, spec in enumerate(runs):
        label, path = spec.split("=", 1)
        t, ratio, status, ratio_attr = load(path)
        colour = colours.setdefault(label, f"C{len(colours) % 10}")
        ax.plot(t * 1e6, ratio, lw=1.4, label=label, color=colour, ls="-" if i % 2 == 0 else "--")
        stopped = not status.startswith("ok")
        if stopped or ratio.max() > ymax:
            ax.plot(t[-1] * 1e6, ymax, "x", color=colour, ms=9, mew=2, clip_on=False)
            text = f"{label}: stopped, max ratio {ratio_attr:.3g}" if stopped else f"{label}: above {ymax:g}"
            ax.annotate(text, (t[-1] * 1e6, ymax), textcoords="offset points", xytext=(8, -12 - 10 * marked),
                        fontsize=7, color=colour)
            marked += 1
        print(f"{label}: {path}: status {status.split(':')[0]}, max_energy_ratio {ratio_attr:.4f} "
              f"(over every step), E(t_end)/ref {ratio[-1]:.4f}, {len(t)} samples")
    ax.axhline(1.0, color="grey", lw=0.8)
    ax.set_ylim(ymin, ymax)
    ax.set_xlabel("t [us]")
    ax.set_ylabel("E(t) / (E(0) + max |W|)")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower left")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", help="LABEL=FILE.h5")
    parser.add_argument("--right", nargs="*", default=[], help="LABEL=FILE.h5 for a second panel")
    parser.add_argument("--out", required=True)
    parser.add_argument("--title", default="")
    parser.add_argument("--right-title", default="")
    parser.add_argument("--ymin", type=float, default=0.8)
    parser.add_argument("--ymax", type=float, default=1.15)
    parser.add_argument("--right-ymin", type=float, help="lower y limit of the second panel (default: --ymin)")
    args = parser.parse_args()
    panels = 2 if args.right else 1
    fig, axes = plt.subplots(1, panels, figsize=(6.2 * panels, 4.6), squeeze=False)
    colours = {}  # one colour per label in both panels
    panel(axes[0][0], args.runs, args.title, args.ymin, args.ymax, colours)
    if args.right:
        ymin = args.ymin if args.right_ymin is None else args.right_ymin
        panel(axes[0][1], args.right, args.right_title, ymin, args.ymax, colours)
    fig.tight_layout()
    fig.savefig(args.out, dpi=150)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
