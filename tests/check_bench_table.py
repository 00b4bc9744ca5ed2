#!/usr/bin/env python3
"""Smoke test of bench/bench_table (scripts/bench.sh): every row of the throughput,
methods and plastic tables runs and prints a finite positive figure, its met column
agrees with its target, and every case prints phase shares that add up to
100%; the same for --table lme (the methods table's two LME rows) and
--table threads (each case on one and two threads) and --table targets (the
current round's rows, then the plastic and threads tables). Timings are not checked
(--quick sizes, one repetition).

    check_bench_table.py BENCH_TABLE
"""
import math
import re
import subprocess
import sys


def printed_resolution(text):
    """One unit in the last printed digit of a number such as 1.50, 8.19 or 1.02e+07."""
    mantissa, _, exponent = text.lower().partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 10.0 ** (int(exponent or 0) - decimals)


def check(bench_table, args, expected, cases):
    """The failures of one run of bench_table with `args`: `expected` rows per
    table title, `cases` cases with phase shares."""
    out = subprocess.run([bench_table, "--quick", "--repeat", "1"] + args, check=True, capture_output=True, text=True,
                         env={"OMP_NUM_THREADS": "2", "OMP_WAIT_POLICY": "passive"}).stdout
    failures = []
    tables = {}
    title = None
    for line in out.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")] if line.startswith("|") else None
        if cells is None:
            title = None
        elif cells[1:] == ["target", "measured", "met"]:
            title = cells[0]
            tables[title] = []
        elif title and not cells[0].startswith("---"):
            tables[title].append(cells)
    for name, count in expected.items():
        rows = tables.get(name, [])
        if len(rows) != count:
            failures.append(f"{name}: {len(rows)} rows, expected {count}")
        for figure, target, measured, met in rows:
            m = re.match(r"([<>]=?)\s*([0-9.e+-]+)", target)
            v = re.match(r"[0-9.e+-]+", measured)
            if not m or not v:
                failures.append(f"{figure}: cannot read target '{target}' or measured '{measured}'")
                continue
            value, bound = float(v.group(0)), float(m.group(2))
            if not (math.isfinite(value) and value > 0):
                failures.append(f"{figure}: measured {value} is not finite and positive")
            ok = {"<=": value <= bound, "<": value < bound, ">=": value >= bound, ">": value > bound}[m.group(1)]
            # the row judges the unrounded figure: a printed value that rounds to the bound may go either way
            at_bound = abs(value - bound) <= 0.5 * printed_resolution(v.group(0))
            if met not in ("met", "**not met**") or (not at_bound and met != ("met" if ok else "**not met**")):
                failures.append(f"{figure}: measured {value}, target {target}, but the row says '{met}'")
    shares = re.findall(r"^  (\S.*?)\s{2,}(basis .*)$", out, re.M)
    if len(shares) != cases:
        failures.append(f"phase shares of {len(shares)} cases, expected {cases}")
    for case, text in shares:
        total = sum(float(p) for p in re.findall(r"([0-9.]+)%", text))
        if not 97 <= total <= 103:  # each share rounded to 1%: 6 phases
            failures.append(f"{case}: phase shares add up to {total}%")
    if failures:
        print(out)
        return [f"{' '.join(args) or 'all'}: {f}" for f in failures]
    print(f"ok ({' '.join(args) or 'all'}): {sum(len(r) for r in tables.values())} rows, "
          f"{len(shares)} cases with phase shares")
    return []


def main(argv):
    failures = check(argv[1], [], {"throughput figure": 6, "method figure": 8, "plastic figure": 2}, 15)
    # --table lme: lme and lme_box npc against linear fe, 2D and 3D
    failures += check(argv[1], ["--table", "lme"], {"method figure": 4}, 6)
    failures += check(argv[1], ["--table", "threads"], {"threads figure": 7}, 14)
    failures += check(argv[1], ["--table", "targets"],
                      {"target figure": 6, "plastic figure": 2, "threads figure": 7}, 8 + 3 + 14)
    if failures:
        print("\n".join(failures))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
