"""otmpm.convergence: error against run time for any scene, measured against a reference run.

A study (`otmpm study STUDY.toml`, docs/user-guide.md "Studies") whose file has
[[measure]] tables gets, after its runs, a second CSV (STEM_errors.csv beside
its CSV) and plots: each run's measures, their errors against the reference
run, the observed order of convergence and a Richardson estimate. The
measures are computed from the result files:

    extent     max - min of the particles' positions along `axis` at the last frame,
               plus `initial` - (that extent at t = 0) when `initial` (the body's extent) is given
    footprint  the largest distance from the line through `center` along `axis` of the
               particles within `layer` of the lowest one along `axis`, at the last frame,
               plus `initial` - (the largest such distance at t = 0) when `initial` is given
    field      `field` (e.g. "v", "stress") at the last frame, sampled at fixed material points:
               the particles nearest (at t = 0) to `points` = [[x, y, z], ...] or to the
               `grid` = {lower, upper, count} of probe points; or the scene's `probes`
               (["A", ...]) over time
    energy     the energy `series` ("kinetic", "strain", ...) over time

A scalar measure's error is |q - q_ref| (in the measure's units: m for extent
and footprint); an array's error is relative, ||a - a_ref|| / ||a_ref|| (time
series interpolated to the reference's times). The reference (table
[reference]) is each variant's finest run (default), the finest run of one
`variant`, or a result `file`. From Python any function of a Results is a
measure:

    import otmpm
    rows = otmpm.convergence.reference_errors("examples/studies/impactor.toml",
                                              functions={"top": lambda r: r.frames[-1]["x"][:, 2].max()})

Also a script: python3 convergence.py STUDY.toml (what `otmpm study` runs).
"""
import csv
import math
import os
import sys
import tomllib

import numpy as np

try:
    from . import results as _results
except ImportError:  # run as a script from share/otmpm (otmpm study): results.py lies beside it
    import results as _results

#: The measure kinds of a study's [[measure]] tables, with their keys (required, optional).
KINDS = {
    "extent": ({"axis"}, {"initial"}),
    "footprint": ({"axis"}, {"layer", "center", "initial"}),
    "field": ({"field"}, {"points", "grid", "probes"}),
    "energy": ({"series"}, set()),
}


def extent(r, axis, initial=None):
    """max - min of the particles' x along `axis` at the last frame (+ initial - that at t = 0)."""
    x = r.frames[-1]["x"][:, axis]
    value = float(x.max() - x.min())
    if initial is not None:
        x0 = r.frames[0]["x"][:, axis]
        value += initial - float(x0.max() - x0.min())
    return value


def _radius(x, axis, center, layer):
    low = x[:, axis] < x[:, axis].min() + layer
    d = np.delete(x[low] - center[: x.shape[1]], axis, axis=1)
    return float(np.sqrt((d**2).sum(axis=1)).max())


def footprint(r, axis, layer=None, center=None, initial=None):
    """The largest distance from the axis line through `center` of the particles within
    `layer` (default: a tenth of the extent) of the lowest along `axis`, at the last frame."""
    x = r.frames[-1]["x"]
    center = np.zeros(3) if center is None else np.asarray(center, dtype=float)
    if layer is None:
        layer = 0.1 * float(x[:, axis].max() - x[:, axis].min())
    value = _radius(x, axis, center, layer)
    if initial is not None:
        value += initial - _radius(r.frames[0]["x"], axis, center, layer)
    return value


def grid_points(lower, upper, count):
    """The probe points of a grid: count[k] points from lower[k] to upper[k] per axis."""
    axes = [np.linspace(lo, hi, int(n)) for lo, hi, n in zip(lower, upper, count)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(axes))


def field_at(r, field, points):
    """`field` at the last frame of the particles nearest (at t = 0) to the material points."""
    X = r.frames[0]["x"]
    p = np.asarray(points, dtype=float)[:, : X.shape[1]]
    nearest = np.array([int(np.argmin(((X - q) ** 2).sum(axis=1))) for q in p])
    return np.asarray(r.frames[-1][field])[nearest]


def probe_series(r, field, probes):
    """The probes' `field` over time: (time, values stacked over the probes)."""
    t = r.probes[probes[0]]["time"]
    return t, np.stack([np.asarray(r.probes[name][field]).reshape(len(t), -1) for name in probes], axis=1)


def energy_series(r, series):
    """The energy `series` over time: (time, values)."""
    return r.energy["time"], r.energy[series]


def measure(r, spec):
    """The value of one [[measure]] table (a dict) for an open Results: a float, an array, or (time, values)."""
    kind = spec["kind"]
    if kind == "extent":
        return extent(r, spec["axis"], spec.get("initial"))
    if kind == "footprint":
        return footprint(r, spec["axis"], spec.get("layer"), spec.get("center"), spec.get("initial"))
    if kind == "energy":
        return energy_series(r, spec["series"])
    if "probes" in spec:
        return probe_series(r, spec["field"], spec["probes"])
    points = spec["points"] if "points" in spec else grid_points(**spec["grid"])
    return field_at(r, spec["field"], points)


def error(value, reference):
    """|q - q_ref| of scalars; ||a - a_ref|| / ||a_ref|| of arrays and of (time, values) series,
    the series interpolated to the reference's times."""
    if isinstance(value, tuple):
        (t, a), (t_ref, a_ref) = value, reference
        a = np.asarray(a).reshape(len(t), -1)
        a_ref = np.asarray(a_ref).reshape(len(t_ref), -1)
        value = np.stack([np.interp(t_ref, t, a[:, k]) for k in range(a.shape[1])], axis=1)
        reference = a_ref
    if np.ndim(value) == 0:
        return abs(float(value) - float(reference))
    value, reference = np.asarray(value, dtype=float), np.asarray(reference, dtype=float)
    return float(np.linalg.norm(value - reference) / max(np.linalg.norm(reference), 1e-300))


def observed_order(h, e):
    """The observed order between successive runs (coarse to fine): log(e_i / e_i+1) / log(h_i / h_i+1);
    NaN where an error is 0 or missing."""
    orders = [math.nan] * len(h)
    for i in range(1, len(h)):
        if e[i - 1] > 0 and e[i] > 0 and h[i - 1] != h[i]:
            orders[i] = math.log(e[i - 1] / e[i]) / math.log(h[i - 1] / h[i])
    return orders


def richardson(h, q):
    """The Richardson estimate of a scalar's limit from its last three values (coarse to fine, any
    ratios of h): the order p solving (q1 - q2) / (q2 - q3) = (h1^p - h2^p) / (h2^p - h3^p),
    then q3 + (q3 - q2) / ((h2 / h3)^p - 1). (NaN, NaN) when the values do not converge monotonically."""
    if len(q) < 3 or not all(math.isfinite(v) for v in q[-3:]):
        return math.nan, math.nan
    (h1, h2, h3), (q1, q2, q3) = h[-3:], q[-3:]
    if (q1 - q2) * (q2 - q3) <= 0:
        return math.nan, math.nan
    ratio = (q1 - q2) / (q2 - q3)

    def f(p):
        return (h1**p - h2**p) / (h2**p - h3**p) - ratio

    lo, hi = 0.05, 10.0
    if f(lo) * f(hi) > 0:
        return math.nan, math.nan
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(lo) * f(mid) > 0 else (lo, mid)
    p = 0.5 * (lo + hi)
    return q3 + (q3 - q2) / ((h2 / h3) ** p - 1), p


def _study(path):
    """The study file's keys that concern the errors, with its paths resolved."""
    with open(path, "rb") as f:
        s = tomllib.load(f)
    folder = os.path.dirname(os.path.abspath(path))
    stem = os.path.splitext(os.path.basename(path))[0]
    csv_path = os.path.join(folder, s.get("csv", stem + ".csv"))
    results = os.path.join(folder, s.get("results", os.path.splitext(os.path.basename(csv_path))[0] + "_results"))
    reference = dict(s.get("reference", {}))
    if "file" in reference:
        reference["file"] = os.path.join(folder, reference["file"])
    return csv_path, results, reference, s.get("measure", [])


def _stem(variant, mesh):
    """The result file name of a run (as the study's file_stem)."""
    name = variant + "_" + mesh
    return "".join(c if c.isalnum() or c in "-." else "_" for c in name)


def reference_errors(study_file, functions=None, out=None):
    """The errors of a finished study's runs against its reference run: one dict per run of its CSV,
    coarse to fine within each variant, with variant, mesh, h, wall_seconds, status and, per measure M
    (the file's [[measure]] tables, then `functions`: name -> f(Results)), M (a scalar's value), M_error,
    M_order (observed order against the next coarser run) and, for scalars, M_richardson (the estimate
    of the limit) and M_richardson_error (|M - M_richardson|). Runs that did not finish ok get empty
    cells. Written to `out` (default: the CSV's STEM_errors.csv) unless out is False."""
    csv_path, results_dir, reference, specs = _study(study_file)
    measures = [(m["name"], (lambda r, m=m: measure(r, m))) for m in specs]
    measures += list((functions or {}).items())
    with open(csv_path, newline="") as f:
        runs = [row for row in csv.DictReader(f)]
    values = {}
    for row in runs:
        if row["status"] != "ok":
            continue
        with _results.open(os.path.join(results_dir, _stem(row["variant"], row["mesh"]) + ".h5")) as r:
            values[(row["variant"], row["mesh"])] = {name: f(r) for name, f in measures}
    by_variant = {}
    for row in runs:
        by_variant.setdefault(row["variant"], []).append(row)
    ref_of = _references(by_variant, values, reference, measures)
    table = []
    for variant, rows in by_variant.items():
        rows.sort(key=lambda row: -float(row["h"]))
        out_rows = [{"variant": variant, "mesh": row["mesh"], "h": float(row["h"]),
                     "wall_seconds": _float(row["wall_seconds"]), "status": row["status"]} for row in rows]
        for name, _ in measures:
            _fill(out_rows, values, variant, name, ref_of(variant))
        table += out_rows
    if out is not False:
        _write(out or os.path.splitext(csv_path)[0] + "_errors.csv", table, [name for name, _ in measures])
    return table


def _float(text):
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def _references(by_variant, values, reference, measures):
    """variant -> the reference's measure values (dict name -> value), or None."""
    if "file" in reference:
        with _results.open(reference["file"]) as r:
            fixed = {name: f(r) for name, f in measures}
        return lambda variant: fixed

    def finest(variant):
        ok = [row for row in by_variant.get(variant, []) if (row["variant"], row["mesh"]) in values]
        if not ok:
            return None
        row = min(ok, key=lambda row: float(row["h"]))
        return values[(row["variant"], row["mesh"])]

    if "variant" in reference:
        fixed = finest(reference["variant"])
        return lambda variant: fixed
    return finest


def _fill(rows, values, variant, name, ref):
    """The columns of measure `name` for one variant's rows (coarse to fine)."""
    for row in rows:
        v = values.get((variant, row["mesh"]), {}).get(name)
        scalar = v is not None and not isinstance(v, tuple) and np.ndim(v) == 0
        row[name] = float(v) if scalar else math.nan
        row[name + "_error"] = error(v, ref[name]) if v is not None and ref is not None else math.nan
    ok = [row for row in rows if math.isfinite(row[name + "_error"]) and row[name + "_error"] > 0]
    for row, p in zip(ok, observed_order([row["h"] for row in ok], [row[name + "_error"] for row in ok])):
        row[name + "_order"] = p
    scalars = [row for row in rows if math.isfinite(row[name])]
    limit, _ = richardson([row["h"] for row in scalars], [row[name] for row in scalars])
    for row in rows:
        row.setdefault(name + "_order", math.nan)
        row[name + "_richardson"] = limit
        row[name + "_richardson_error"] = abs(row[name] - limit) if math.isfinite(row[name]) else math.nan


def _write(path, table, names):
    columns = ["variant", "mesh", "h", "wall_seconds", "status"]
    for name in names:
        columns += [name, name + "_error", name + "_order", name + "_richardson", name + "_richardson_error"]
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(columns)
        for row in table:
            w.writerow(["" if isinstance(row[c], float) and not math.isfinite(row[c]) else
                        (f"{row[c]:.8g}" if isinstance(row[c], float) else row[c]) for c in columns])


def main(argv):
    """python3 convergence.py STUDY.toml [--plots]: writes the errors CSV and, with --plots, one
    work-precision and one convergence plot per measure (plot_study.py beside this file)."""
    if len(argv) < 2:
        print(main.__doc__, file=sys.stderr)
        return 2
    table = reference_errors(argv[1])
    csv_path = os.path.splitext(_study(argv[1])[0])[0] + "_errors.csv"
    print(f"errors against the reference run: {csv_path} ({len(table)} runs)")
    if "--plots" in argv:
        here = os.path.dirname(os.path.abspath(__file__))
        sys.path.insert(0, here)
        import plot_study

        for spec in _study(argv[1])[3]:
            name = spec["name"]
            prefix = os.path.splitext(csv_path)[0] + "_" + name
            plot_study.main([csv_path, "--error", name + "_error", "--out", prefix, "--order", name + "_order",
                             "--estimate", name + "_richardson_error"])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
