#!/usr/bin/env python3
"""Compares two otmpm result files frame by frame (docs/user-guide.md,
"Distributed runs"): the same frames, the same datasets of the same shape,
and for every particle field the largest difference relative to the field's
largest magnitude,

    max_p |a_p - b_p| / max_p |a_p|      (per field, over all frames),

printed per field. Exit status 1 when a field differs by more than --tol
(default 1e-12), when the frames or datasets differ, or with --bitwise when
any value differs at all; 0 otherwise.

A symmetric tensor (output.symmetric_tensors, the dataset attribute
`components`) is compared by its named components; when the two files name
different ones - a 2D stress "xx xy yy zz" against the "xx xy yy" of otmpm
before plane strain's sigma_zz was stored - the components both have are
compared and the others are listed once (not a failure).

    /usr/bin/python3 scripts/compare_results.py serial.h5 mpi.h5 [--tol 1e-12] [--fields x,stress] [--bitwise]
"""
import argparse
import sys

import h5py
import numpy as np

from tree_results import link_names


def frames(f):
    """The frame names, sorted (listed as otmpm.results does: safe on a killed run's file)."""
    return link_names(f["frames"])


def histories(f):
    """Paths of the history datasets: probes, walls and root-level series (every dataset outside /frames).
    Walked with link_names (h5py's visititems lists in name order, which crashes libhdf5 on a killed run's file)."""
    out = []

    def walk(group):
        for name in link_names(group):
            obj = group[name]
            if isinstance(obj, h5py.Dataset):
                out.append(obj.name)
            elif isinstance(obj, h5py.Group) and obj.name != "/frames":
                walk(obj)

    walk(f["/"])
    return sorted(out)


def components(dataset):
    """The names of a dataset's columns (attribute `components`), or None."""
    names = dataset.attrs.get("components")
    if names is None:
        return None
    return (names.decode() if isinstance(names, bytes) else str(names)).split()


def common_columns(da, db, noted):
    """The datasets' values restricted to the components both name (None, None
    when they name none or the same); the others noted once per field."""
    ca, cb = components(da), components(db)
    if ca is None or cb is None or ca == cb:
        return None, None
    both = [c for c in ca if c in cb]
    key = (da.name.rsplit("/", 1)[-1], tuple(ca), tuple(cb))
    if key not in noted:
        noted.add(key)
        print(f"field {key[0]}: components {' '.join(ca)} vs {' '.join(cb)}: comparing {' '.join(both)}")
    return da[()][:, [ca.index(c) for c in both]], db[()][:, [cb.index(c) for c in both]]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--tol", type=float, default=1e-12)
    ap.add_argument("--fields", default="", help="comma-separated fields to compare (default: all)")
    ap.add_argument("--bitwise", action="store_true", help="every value must be the same bits")
    ap.add_argument("--last", action="store_true", help="compare the last frame only")
    args = ap.parse_args()
    wanted = [f for f in args.fields.split(",") if f]
    worst = {}
    noted = set()
    with h5py.File(args.a, "r") as fa, h5py.File(args.b, "r") as fb:
        na, nb = frames(fa), frames(fb)
        if na != nb:
            print(f"frames differ: {len(na)} vs {len(nb)}")
            return 1
        for name in na[-1:] if args.last else na:
            ga, gb = fa["frames"][name], fb["frames"][name]
            ta, tb = ga.attrs["time"], gb.attrs["time"]
            if abs(ta - tb) > args.tol * max(abs(ta), abs(tb)) or (args.bitwise and ta != tb):
                print(f"frame {name}: time {ga.attrs['time']!r} vs {gb.attrs['time']!r}")
                return 1
            fields = link_names(ga)
            if fields != link_names(gb):
                print(f"frame {name}: datasets {fields} vs {link_names(gb)}")
                return 1
            for field in fields:
                if wanted and field not in wanted:
                    continue
                a, b = common_columns(ga[field], gb[field], noted)
                if a is None:
                    a, b = ga[field][()], gb[field][()]
                if a.shape != b.shape:
                    print(f"frame {name} field {field}: shape {a.shape} vs {b.shape}")
                    return 1
                if args.bitwise and a.tobytes() != b.tobytes():
                    print(f"frame {name} field {field}: not the same bits")
                    return 1
                scale = np.max(np.abs(a)) if a.size else 0.0
                diff = np.max(np.abs(a - b)) if a.size else 0.0
                rel = diff / scale if scale > 0 else diff
                worst[field] = max(worst.get(field, 0.0), rel)
        # histories: /probes/<name>/<field> and root-level series (/energy/<field>)
        for path in histories(fa):
            if wanted:
                break
            if path not in fb:
                print(f"history {path} missing in {args.b}")
                return 1
            a, b = fa[path][()], fb[path][()]
            if a.shape != b.shape:
                print(f"history {path}: shape {a.shape} vs {b.shape}")
                return 1
            if args.bitwise and a.tobytes() != b.tobytes():
                print(f"history {path}: not the same bits")
                return 1
            scale = np.max(np.abs(a)) if a.size else 0.0
            rel = (np.max(np.abs(a - b)) / scale if scale > 0 else np.max(np.abs(a - b))) if a.size else 0.0
            worst[path] = max(worst.get(path, 0.0), rel)
    status = 0
    for field, rel in sorted(worst.items()):
        flag = ""
        if rel > args.tol:
            flag = f"  > {args.tol:g}"
            status = 1
        print(f"{field:24s} {rel:.3e}{flag}")
    return status


if __name__ == "__main__":
    sys.exit(main())
