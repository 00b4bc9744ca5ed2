#!/usr/bin/env python3
"""A scaling model of distributed otmpm runs, built from measurements on one
machine (docs/performance.md, "Distributed runs"), predicting the parallel
efficiency and memory per rank of a large 3D run on many ranks.

    /usr/bin/python3 scripts/scaling-model.py --step-seconds-per-particle T \\
        --halo-bytes-per-face-node B --exchanges-per-step X --reductions-per-step R \\
        --bytes-per-particle P [--particles 1e9] [--ppc 8] [--ranks 64 1000 10000] \\
        [--bandwidth 100e9] [--latency 2e-6]

The model, per step and rank, for a cube of `particles` in cells of `ppc`
particles divided into `ranks` cubic subdomains of n^3 cells:

    compute  = particles / ranks * T                  (T: one core's time per particle-step)
    halo     = 6 n^2 * B                              (B: bytes per face node and step, both exchanges)
    network  = 26 X * latency + halo / bandwidth      (X: halo exchanges per step, each a message
                                                       to each of the 26 neighbours of a cube)
             + R * 2 ceil(log2 ranks) * latency       (R: ordered reductions, binomial tree up and down)
    efficiency = compute / (compute + network)        (no overlap of communication and compute)

Memory per rank while stepping: particles / ranks * P (P: bytes per particle,
nodes and ghosts included, measured), and while writing a checkpoint:
particles / ranks * C (C: --checkpoint-bytes-per-particle, measured). Each
rank seeds only its own cells and builds only its window of the lattice,
so its set-up stays within its stepping memory (measured: the peaks of a
run without checkpoints are its stepping's).

The figures of docs/performance.md ("A cluster run, on paper"), from the
3D block measured on 4 ranks (2.2e7 particles) and run --check's calibration:

    /usr/bin/python3 scripts/scaling-model.py --step-seconds-per-particle 0.28e-6 \
        --halo-bytes-per-face-node 56 --exchanges-per-step 1 --reductions-per-step 2 \
        --bytes-per-particle 694 --checkpoint-bytes-per-particle 898
"""
import argparse
import math


def predict(a, ranks):
    per_rank = a.particles / ranks
    cells = a.particles / a.ppc / ranks
    n = cells ** (1.0 / 3.0)
    compute = per_rank * a.step_seconds_per_particle
    halo = 6.0 * n * n * a.halo_bytes_per_face_node if ranks > 1 else 0.0
    levels = math.ceil(math.log2(ranks)) if ranks > 1 else 0
    network = (26 * a.exchanges_per_step * a.latency + halo * 8.0 / a.bandwidth +
               a.reductions_per_step * 2 * levels * a.latency) if ranks > 1 else 0.0
    return {
        "ranks": ranks,
        "particles/rank": per_rank,
        "n (cells/side)": n,
        "compute ms": 1e3 * compute,
        "halo KB": halo / 1e3,
        "network ms": 1e3 * network,
        "efficiency": compute / (compute + network),
        "memory GB": per_rank * a.bytes_per_particle / 1e9,
        "checkpoint GB": per_rank * a.checkpoint_bytes_per_particle / 1e9,
    }


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--step-seconds-per-particle", type=float, required=True)
    p.add_argument("--halo-bytes-per-face-node", type=float, required=True)
    p.add_argument("--exchanges-per-step", type=float, required=True)
    p.add_argument("--reductions-per-step", type=float, required=True)
    p.add_argument("--bytes-per-particle", type=float, required=True)
    p.add_argument("--checkpoint-bytes-per-particle", type=float, required=True)
    p.add_argument("--particles", type=float, default=1e9)
    p.add_argument("--ppc", type=float, default=8)
    p.add_argument("--ranks", type=int, nargs="+", default=[64, 1000, 10000])
    p.add_argument("--bandwidth", type=float, default=100e9, help="bits per second")
    p.add_argument("--latency", type=float, default=2e-6, help="seconds per message")
    a = p.parse_args()
    rows = [predict(a, r) for r in a.ranks]
    keys = list(rows[0])
    print(" ".join(f"{k:>15s}" for k in keys))
    for r in rows:
        print(" ".join(f"{r[k]:15.4g}" for k in keys))


if __name__ == "__main__":
    main()
