#!/usr/bin/env python3
"""Compares the rows of the throughput table (bench/bench_table) of two builds,
interleaved: one repetition of the old binary, one of the new, in turn, for
R rounds, so that the machine's drift hits both alike. Prints per row the
median of each and the median of the per-round ratios new/old.

    /usr/bin/python3 scripts/bench-compare.py OLD/bench_table NEW/bench_table [--rounds R]

Rows: the median time per particle-step of each case (lower is better) and
the table's figures (particle-steps/s, ratios, peak RSS per particle).
Both run with OMP_NUM_THREADS=2 and OMP_WAIT_POLICY=passive, as scripts/bench.sh.
"""
import argparse
import os
import re
import statistics
import subprocess


def run(binary):
    env = dict(os.environ, OMP_NUM_THREADS="2", OMP_WAIT_POLICY="passive")
    out = subprocess.run([binary, "--repeat", "1"], env=env, check=True, capture_output=True, text=True).stdout
    rows = {}
    for name, value in re.findall(r"^\s+(.+?)\s{2,}([0-9.]+) us$", out, re.M):
        rows[f"us per particle-step: {name}"] = float(value)
    for figure, value in re.findall(r"^\| (.+?) \| [^|]+ \| ([0-9.e+-]+)", out, re.M):
        rows[figure] = float(value)
    return rows


def main():
    p = argparse.ArgumentParser()
    p.add_argument("old")
    p.add_argument("new")
    p.add_argument("--rounds", type=int, default=5)
    a = p.parse_args()
    old, new = [], []
    for r in range(a.rounds):
        old.append(run(a.old))
        new.append(run(a.new))
        print(f"round {r + 1} of {a.rounds} done", flush=True)
    print(f"{'row':75s} {'old':>10s} {'new':>10s} {'new/old':>8s}  per-round ratios")
    for row in old[0]:
        if not all(row in o and row in n for o, n in zip(old, new)):
            continue
        ratios = [n[row] / o[row] for o, n in zip(old, new) if o[row] != 0]
        print(f"{row[:75]:75s} {statistics.median(o[row] for o in old):10.4g} "
              f"{statistics.median(n[row] for n in new):10.4g} {statistics.median(ratios):8.3f}  "
              + " ".join(f"{x:.3f}" for x in ratios))


if __name__ == "__main__":
    main()
