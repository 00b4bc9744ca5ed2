#!/usr/bin/env python3
"""otmpm render: the particles of an otmpm result file coloured by a field.

Run through `otmpm render RESULT.h5 --field NAME [--frame K | --all] --out
FILE.png|.gif` (the binary finds this script in PREFIX/share/otmpm); it can
also be run directly with the same arguments.

What is drawn:
  1D  the field against the particle position x (one point per particle,
      coloured by the same value);
  2D  the particles in the x-y plane as squares of the mean particle spacing,
      to scale (a body more than 6 times longer than high: "not to scale");
  3D  the particles projected on a plane (--view xy: seen from +z, the
      particles with the largest z drawn last, i.e. on top; xz, yz likewise).
A vector field is shown by its Euclidean norm, a tensor field (stress,
strain, F: D*D components, row-major) by its Frobenius norm, unless
--component picks one (x, y, z; xx, xy, ...; or the column index). In 2D,
--field stress --component zz is plane strain's sigma_zz (the "zz" column of
a symmetric stress, output.symmetric_tensors, or the field stress_zz); the
norm stays that of the in-plane D*D tensor. The
colour limits are those of all frames drawn (a GIF keeps one scale); a field
that takes both signs gets a diverging map centred on 0. Axes are in metres,
the title gives the time.

Exit status: 0 ok, 2 bad input (missing or unreadable file, unknown field -
the message lists the fields -, frame out of range, missing numpy, h5py or
matplotlib).
"""

import argparse
import os
import sys


def fail(message):
    print(f"otmpm render: error: {message}", file=sys.stderr)
    sys.exit(2)


# Reading never takes HDF5's file lock, so a run that is still writing can be
# looked at (the frames it has flushed are complete).
os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")
try:
    import numpy as np
    import h5py
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import PillowWriter
    from matplotlib.colors import Normalize
except ImportError as e:
    fail(f"needs Python 3 with numpy, h5py and matplotlib ({e}); on Debian: "
         "apt-get install python3-matplotlib python3-h5py")

UNITS = {"x": "m", "displacement": "m", "v": "m/s", "a": "m/s^2", "stress": "Pa", "stress_zz": "Pa", "strain": "1", "F": "1",
         "density": "kg/m^3", "mass": "kg"}
AXES = "xyz"


def link_names(group):
    """The names in a group, sorted: its name index walked in native order.
    h5py's iteration (increasing name order) crashes libhdf5 on a group a
    killed run left half-written (otmpm.results.link_names); the frames found
    are drawn, with a warning when the stored link count differs."""
    names = []
    group.id.links.iterate(names.append, idx_type=h5py.h5.INDEX_NAME, order=h5py.h5.ITER_NATIVE)
    if len(names) != len(group):
        print(f"otmpm render: warning: {group.file.filename}: group {group.name} records {len(group)} links but "
              f"holds {len(names)} (a damaged file, e.g. left by a killed run)", file=sys.stderr)
    return sorted(n.decode() for n in names)


def text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def scalar(value, what):
    """An HDF5 attribute that must be one number (an array or a string is not)."""
    a = np.asarray(value)
    if a.shape not in ((), (1,)) or not np.issubdtype(a.dtype, np.number):
        raise ValueError(f"{what} is not a number ({a.dtype} of shape {a.shape})")
    return a.reshape(()).item()


class Result:
    """The frames of a result file: times, positions and one field. Every
    part is checked as it is read: a file of another program (a dataset named
    frames, an attribute that is an array) is bad input, never a traceback."""

    def __init__(self, path):
        try:
            self.file = h5py.File(path, "r")
        except OSError as e:
            fail(f"{path}: cannot read it as an otmpm result file ({e})")
        frames = self.file.get("frames")
        if not isinstance(frames, h5py.Group) or len(frames) == 0:
            fail(f"{path}: no frames (not an otmpm result file, or the run wrote none)")
        self.path = path
        self.names = link_names(frames)
        if "dimension" in self.file.attrs:
            dim = scalar(self.file.attrs["dimension"], "the attribute 'dimension'")
        else:
            dim = self.frame(0)["x"].shape[1]
        if dim not in (1, 2, 3):
            fail(f"{path}: the dimension {dim!r} is not 1, 2 or 3 (not an otmpm result file?)")
        self.dim = int(dim)
        self.status = text(self.file.attrs.get("status", ""))

    def fields(self):
        return [name for name in link_names(self.frame(0)) if name != "x3"]

    def frame(self, k):
        group = self.file["frames"][self.names[k]]
        if not isinstance(group, h5py.Group):
            raise ValueError(f"frame {self.names[k]} is not a group")
        return group

    def time(self, k):
        return float(scalar(self.frame(k).attrs.get("time"), f"the time of frame {self.names[k]}"))


def component_of(field, cols, dim, component):
    """(column index or None for the norm, label) of --component for a field of `cols` columns."""
    if cols == 1:  # a scalar, or a 1D vector or tensor: its one component, with its sign
        if component not in ("norm", "0", "x", "xx"):
            fail(f"--component {component}: {field} has one component here (x, or norm)")
        return 0, field
    names = list(AXES[:dim]) if cols == dim else [a + b for a in AXES[:dim] for b in AXES[:dim]]
    if cols not in (dim, dim * dim):
        names = [str(i) for i in range(cols)]
    if component == "norm":
        return None, f"|{field}|"
    if component in names:
        return names.index(component), f"{field}_{component}"
    if component.isdigit() and int(component) < cols:
        return int(component), f"{field}_{names[int(component)]}"
    fail(f"--component {component}: {field} has {cols} components ({', '.join(names)}) or norm")


def unpack_symmetric(data, components, dim):
    """A symmetric tensor stored by its independent components (dataset
    attribute `components`, output.symmetric_tensors) as row-major D*D rows."""
    names = components.split()
    full = np.empty((data.shape[0], dim * dim))
    for c, name in enumerate(names):
        if max(AXES.index(name[0]), AXES.index(name[1])) >= dim:
            continue  # out of plane: the "zz" of a 2D stress (out_of_plane)
        i, j = AXES.index(name[0]), AXES.index(name[1])
        full[:, i * dim + j] = full[:, j * dim + i] = data[:, c]
    return full


def read_field(result, k, field):
    """Field `field` of frame k as doubles, (n, cols); a symmetric tensor's components expanded to D*D."""
    dataset = result.frame(k)[field]
    data = np.asarray(dataset[:], dtype=float)
    if data.ndim == 1:
        data = data[:, None]
    components = dataset.attrs.get("components")
    if components is not None:
        data = unpack_symmetric(data, text(components), result.dim)
    return data


def out_of_plane(result, k):
    """Plane strain's sigma_zz of frame k (2D): the "zz" column of a symmetric
    stress, else the field stress_zz; None when the frame has neither."""
    frame = result.frame(k)
    if "stress" in frame:
        names = text(frame["stress"].attrs.get("components", "")).split()
        if "zz" in names:
            return np.asarray(frame["stress"][:, names.index("zz")], dtype=float)
    if "stress_zz" in frame:
        return np.asarray(frame["stress_zz"][:], dtype=float).reshape(-1)
    return None


def values(result, k, field, column):
    if column == "zz":
        return out_of_plane(result, k)
    data = read_field(result, k, field)
    return np.linalg.norm(data, axis=1) if column is None else data[:, column]


def positions(result, k):
    return np.asarray(result.frame(k)["x"][:], dtype=float).reshape(-1, result.dim)


def colour_scale(lo, hi):
    """A Normalize and a colour map: diverging and centred on 0 when the values take both signs."""
    if lo < 0 < hi:
        m = max(-lo, hi)
        return Normalize(-m, m), "coolwarm"
    if lo == hi:
        pad = abs(lo) * 1e-3 or 1.0
        lo, hi = lo - pad, hi + pad
    return Normalize(lo, hi), "viridis"


def plane(dim, view):
    """Axis indices (horizontal, vertical, depth) of the picture."""
    if dim < 3:
        return 0, 1, None
    a, b = AXES.index(view[0]), AXES.index(view[1])
    return a, b, 3 - a - b


def particle_spacing(x):
    """Mean particle spacing s: the body's extent per axis is the particles' range plus one s (half a
    spacing beyond the outermost particle on each side), and (product of the extents / count)^(1/D) = s."""
    ext = np.ptp(x, axis=0)
    ext = ext[ext > 0]
    if len(x) < 2 or ext.size == 0:
        return 0.0
    s = float((np.prod(ext) / len(x)) ** (1.0 / ext.size))
    for _ in range(20):  # a fixed point, reached in a few steps
        s = float((np.prod(ext + s) / len(x)) ** (1.0 / ext.size))
    return s


def stretched(frame_limits):
    """True when the picture is too flat (or tall) to draw to scale: a 2D bar 40 times longer than high."""
    (x0, x1), (y0, y1) = frame_limits
    aspect = (y1 - y0) / (x1 - x0)
    return not 0.15 <= aspect <= 6.0


def figure_size(dim, frame_limits):
    """Width 7 in; in 2D/3D the height that keeps the axes to scale (when not stretched)."""
    if dim == 1 or stretched(frame_limits):
        return 7.0, 4.5
    (x0, x1), (y0, y1) = frame_limits
    return 7.0, float(np.clip(0.72 * 7.0 * (y1 - y0) / (x1 - x0) + 1.3, 2.5, 9.0))


def limits(result, frames, axes):
    xs = np.concatenate([positions(result, k) for k in frames])
    out = []
    for a in axes:
        lo, hi = xs[:, a].min(), xs[:, a].max()
        pad = 0.05 * (hi - lo) if hi > lo else (abs(lo) * 0.05 or 1.0)
        out.append((lo - pad, hi + pad))
    return out


def draw(ax, result, k, field, column, label, norm, cmap, frame_limits, view):
    x = positions(result, k)
    c = values(result, k, field, column)
    unit = UNITS.get(field, "")
    if result.dim == 1:
        ax.scatter(x[:, 0], c, c=c, cmap=cmap, norm=norm, s=12)
        ax.set_xlim(*frame_limits[0])
        lo, hi = norm.vmin, norm.vmax
        pad = 0.05 * (hi - lo)
        ax.set_ylim(lo - pad, hi + pad)
        ax.set_xlabel("x [m]")
        ax.set_ylabel(f"{label} [{unit}]" if unit else label)
        ax.grid(True, alpha=0.3)
    else:
        h, v, depth = plane(result.dim, view)
        order = np.argsort(x[:, depth], kind="stable") if depth is not None else np.arange(len(x))
        (x0, x1), (y0, y1) = frame_limits
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        flat = stretched(frame_limits)
        ax.set_aspect("auto" if flat else "equal")
        # Squares of the mean particle spacing, in points (the smaller scale of the two axes).
        fig = ax.figure
        fig.canvas.draw()
        box = ax.get_window_extent()
        per_metre = min(box.width / (x1 - x0), box.height / (y1 - y0)) * 72 / fig.dpi
        side = 1.15 * particle_spacing(x) * per_metre  # a little overlap: no pixel gaps between squares
        ax.scatter(x[order, h], x[order, v], c=c[order], cmap=cmap, norm=norm, s=max(side * side, 1.0), marker="s",
                   linewidths=0)
        ax.set_xlabel(f"{AXES[h]} [m]")
        ax.set_ylabel(f"{AXES[v]} [m]" + (" (not to scale)" if flat else ""))
    status = "" if result.status in ("ok", "") else f", status {result.status}"
    ax.set_title(f"{label} at t = {result.time(k):.4g} s (frame {k} of {len(result.names) - 1}{status})",
                 fontsize=10)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("result")
    p.add_argument("--field", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--frame", type=int, default=-1)
    p.add_argument("--all", action="store_true")
    p.add_argument("--component", default="norm")
    p.add_argument("--view", default="xy", choices=["xy", "xz", "yz"])
    p.add_argument("--fps", type=float, default=10.0)  # finite, 0.1 to 100 (checked below)
    p.add_argument("--stride", type=int, default=1)
    a = p.parse_args()
    ext = os.path.splitext(a.out)[1].lower()
    if ext not in (".png", ".gif"):
        fail(f"--out {a.out}: the picture must be a .png or a .gif")
    if a.all and ext != ".gif":
        fail("--all draws every frame: use --out FILE.gif")
    if not 0.1 <= a.fps <= 100.0:  # NaN fails too
        fail(f"--fps {a.fps}: must be a number from 0.1 to 100")
    if not os.path.isfile(a.result):  # also no FIFO: h5py would wait on it for ever
        fail(f"{a.result}: no such result file (or not a regular file)")
    if os.path.exists(a.out) and os.path.samefile(a.out, a.result):
        fail(f"--out {a.out} is the result file {a.result} (or a link to it): the picture would replace the results")
    result = Result(a.result)
    fields = result.fields()
    if a.field not in fields:
        fail(f"{a.result}: no field '{a.field}' in the frames; fields: {', '.join(fields)}")
    if "x" not in fields:
        fail(f"{a.result}: the frames hold no positions (add \"x\" to output.fields)")
    n = len(result.names)
    if a.stride < 1:
        fail(f"--stride {a.stride}: must be >= 1")
    if a.all:
        frames = list(range(0, n, a.stride))
        if frames[-1] != n - 1:
            frames.append(n - 1)  # always end on the last frame
    else:
        if not -n <= a.frame < n:
            fail(f"frame {a.frame} out of range: {a.result} has {n} frames (0 to {n - 1}, or -1 to -{n})")
        frames = [a.frame % n]
    if result.dim == 3 and a.view not in ("xy", "xz", "yz"):
        fail(f"--view {a.view}")
    cols = read_field(result, 0, a.field).shape[1]
    if result.dim == 2 and a.field == "stress" and a.component == "zz":
        if any(out_of_plane(result, k) is None for k in frames):
            fail(f"{a.result}: --component zz: the frames hold no sigma_zz (run with output.symmetric_tensors = true "
                 "or \"stress_zz\" in output.fields)")
        column, label = "zz", "stress_zz"
    else:
        column, label = component_of(a.field, cols, result.dim, a.component)
    all_values = np.concatenate([values(result, k, a.field, column) for k in frames])
    finite = all_values[np.isfinite(all_values)]
    norm, cmap = colour_scale(finite.min(), finite.max()) if finite.size else colour_scale(0.0, 0.0)
    h, v, _ = plane(result.dim, a.view)
    frame_limits = limits(result, frames, [h] if result.dim == 1 else [h, v])
    fig, ax = plt.subplots(figsize=figure_size(result.dim, frame_limits), dpi=100, layout="constrained")
    bar = fig.colorbar(plt.cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax)
    unit = UNITS.get(a.field, "")
    bar.set_label(f"{label} [{unit}]" if unit else label)
    fig.suptitle(os.path.basename(a.result), fontsize=9, color="0.35")
    if ext == ".png":
        draw(ax, result, frames[0], a.field, column, label, norm, cmap, frame_limits, a.view)
        fig.savefig(a.out)
    else:
        writer = PillowWriter(fps=a.fps)
        with writer.saving(fig, a.out, dpi=fig.dpi):
            for k in frames:
                ax.clear()
                draw(ax, result, k, a.field, column, label, norm, cmap, frame_limits, a.view)
                writer.grab_frame()
    print(f"wrote {a.out} ({len(frames)} frame{'s' if len(frames) > 1 else ''}, {label})")


if __name__ == "__main__":
    try:
        main()
    except Exception as e:  # h5py's errors on a damaged file, a file of another program: exit 2, no traceback
        result = sys.argv[1] if len(sys.argv) > 1 else "the result file"
        other = getattr(e, "filename", None)
        if isinstance(e, OSError) and other is not None and os.path.abspath(str(other)) != os.path.abspath(result):
            fail(f"{other}: {e.strerror or e}")  # another file, e.g. --out in a missing directory
        fail(f"{result}: cannot read it as an otmpm result file (a damaged file, or another program's?): "
             f"{type(e).__name__}: {e}")
