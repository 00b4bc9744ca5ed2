#!/usr/bin/python3
"""What the Python package costs (docs/performance-log-2026.md, "Python package").

1. otmpm.run against the command line on the same scene (default
   examples/dyka/dyka_n133.toml, with its result file): REPEAT runs of each,
   interleaved (CLI, Python, CLI, Python, ...) so that a drift of the
   machine's speed hits both alike. Two figures per run: the run's own wall
   time (the `wall_seconds` it reports: stepping and writing, the same code)
   and the end-to-end time (the CLI process from start to exit, against
   Scene.from_toml + otmpm.run in this process), as wall time and as CPU
   time (user + system: the CLI process's, this process's during the call;
   CPU time does not count the time a loaded machine leaves a process
   waiting). A third run per repetition calls otmpm.run in a new Python
   process, so that both sides start cold (a process that already ran the
   scene runs it again a little faster). Ratios are medians of the
   per-repetition ratios.
2. The overhead of sim.step() called from Python: a one-particle scene
   (linear basis, fe, fixed dt; a step is mostly the fixed cost of the step
   loop), STEPS steps as `for _ in range(STEPS): sim.step()`, against
   sim.step(STEPS) (the same loop in C++ inside the module) and against
   bench_sim_step (a C++ program looping Simulation::step() itself),
   interleaved, REPEAT times each, medians.

    OMP_NUM_THREADS=1 PYTHONPATH=build/python /usr/bin/python3 bench/bench_python.py \\
        [--build build] [--repeat 11] [--steps 10000] [--scene examples/dyka/dyka_n133.toml]
"""
import argparse
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")  # both sides alike, before the OpenMP runtime starts
os.environ.setdefault("OMP_WAIT_POLICY", "passive")
import h5py  # noqa: E402

import otmpm  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: One particle at rest in a one-cell grid: a step is little more than the loop's fixed cost.
ONE_PARTICLE = {
    "simulation": {"dimension": 1, "mode": "mpm", "integrator": "fe", "t_end": 1.0, "dt": 1e-6},
    "basis": {"kind": "linear"},
    "grid": {"lower": [0.0], "upper": [1.0], "cells": [1]},
    "material": [{"name": "m", "model": "linear_elastic", "density": 1.0, "young": 1.0, "poisson": 0.0}],
    "body": [{"name": "b", "material": "m", "lower": [0.0], "upper": [1.0], "particles_per_cell": 1}],
    "output": {"file": "one_particle.h5", "every": 0.0},
}


def wall_attribute(path):
    with h5py.File(path, "r") as f:
        return float(f.attrs["wall_seconds"])


def children_cpu():
    """CPU seconds (user + system) of the finished child processes so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


FRESH = """
import sys, otmpm
s = otmpm.run(otmpm.Scene.from_toml(sys.argv[1]), out=sys.argv[2])
print(s.wall_seconds)
"""


def fresh_python(scene_path, out):
    """otmpm.run in a new Python process (as the CLI runs in a new process): its run wall time."""
    done = subprocess.run([sys.executable, "-c", FRESH, scene_path, out], capture_output=True, text=True, check=True)
    return float(done.stdout)


def startup_cpu(cli, repeat):
    """Median CPU seconds of `otmpm --version`: loading the command and its libraries."""
    cpu = []
    for _ in range(repeat):
        c0 = children_cpu()
        subprocess.run([cli, "--version"], capture_output=True, check=True)
        cpu.append(children_cpu() - c0)
    return statistics.median(cpu)


def run_vs_cli(cli, scene_path, repeat, work):
    """Interleaved runs; returns lists of (cli_wall, py_wall, cli_total, py_total, cli_cpu, py_cpu)."""
    rows = []
    for r in range(repeat):
        out_cli, out_py = os.path.join(work, f"cli{r}.h5"), os.path.join(work, f"py{r}.h5")
        t0, c0 = time.perf_counter(), children_cpu()
        done = subprocess.run([cli, "run", scene_path, "--out", out_cli, "--quiet"], capture_output=True, text=True)
        cli_total, cli_cpu = time.perf_counter() - t0, children_cpu() - c0
        if done.returncode != 0:
            sys.exit(f"bench_python: {cli} failed: {done.stderr}")
        t0, c0 = time.perf_counter(), time.process_time()
        s = otmpm.run(otmpm.Scene.from_toml(scene_path), out=out_py)
        py_total, py_cpu = time.perf_counter() - t0, time.process_time() - c0
        fresh = fresh_python(scene_path, os.path.join(work, f"fresh{r}.h5"))
        rows.append((wall_attribute(out_cli), s.wall_seconds, cli_total, py_total, cli_cpu, py_cpu, fresh))
        print(f"  repetition {r + 1}: run wall CLI {rows[-1][0]:.4f} s, Python {rows[-1][1]:.4f} s, "
              f"Python in a new process {fresh:.4f} s; end to end CLI {cli_total:.4f} s, Python {py_total:.4f} s; "
              f"CPU CLI {cli_cpu:.4f} s, Python {py_cpu:.4f} s", flush=True)
    return rows


def python_loop(scene, steps):
    sim = otmpm.Simulation(scene, write_results=False)
    sim.step()  # untimed, as in bench_sim_step
    step = sim.step
    t0 = time.perf_counter()
    for _ in range(steps):
        step()
    return (time.perf_counter() - t0) / steps * 1e9


def module_loop(scene, steps):
    sim = otmpm.Simulation(scene, write_results=False)
    sim.step()
    t0 = time.perf_counter()
    sim.step(steps)
    return (time.perf_counter() - t0) / steps * 1e9


def cxx_loop(program, scene_file, steps):
    done = subprocess.run([program, scene_file, "--steps", str(steps), "--repeat", "1"], capture_output=True,
                          text=True, check=True)
    return float(done.stdout.split()[1])


def step_overhead(build, steps, repeat, work):
    scene = otmpm.Scene.from_dict(ONE_PARTICLE)
    scene_file = os.path.join(work, "one_particle.toml")
    with open(scene_file, "w") as f:
        f.write(scene.to_toml())
    program = os.path.join(build, "bench", "bench_sim_step")
    rows = []
    for r in range(repeat):
        rows.append((python_loop(scene, steps), module_loop(scene, steps), cxx_loop(program, scene_file, steps)))
        print(f"  repetition {r + 1}: ns per step: Python loop {rows[-1][0]:.0f}, sim.step(n) {rows[-1][1]:.0f}, "
              f"C++ program {rows[-1][2]:.0f}", flush=True)
    return rows


def median(rows, i):
    return statistics.median(r[i] for r in rows)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"), help="the build tree (bin/otmpm, bench/)")
    ap.add_argument("--repeat", type=int, default=11)
    ap.add_argument("--steps", type=int, default=10000)
    ap.add_argument("--scene", default=os.path.join(ROOT, "examples", "dyka", "dyka_n133.toml"))
    args = ap.parse_args()
    cli = os.path.join(args.build, "bin", "otmpm")
    with open("/proc/cpuinfo") as f:
        cpu = next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), "?")
    print(f"machine: {cpu}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}; Python {platform.python_version()}, "
          f"otmpm {otmpm.__version__}, OMP_NUM_THREADS={os.environ['OMP_NUM_THREADS']}")
    with tempfile.TemporaryDirectory(prefix="bench_python_") as work:
        print(f"1. otmpm.run vs `otmpm run` on {os.path.relpath(args.scene, ROOT)}, {args.repeat} interleaved pairs")
        rows = run_vs_cli(cli, args.scene, args.repeat, work)
        run_ratio = statistics.median(r[1] / r[0] for r in rows)
        total_ratio = statistics.median(r[3] / r[2] for r in rows)
        print(f"run wall (median): CLI {median(rows, 0):.4f} s, Python {median(rows, 1):.4f} s, "
              f"Python/CLI {run_ratio:.4f} ({100 * (run_ratio - 1):+.2f} %)")
        fresh_ratio = statistics.median(r[6] / r[0] for r in rows)
        print(f"run wall, each in a new process (median): CLI {median(rows, 0):.4f} s, Python {median(rows, 6):.4f} s, "
              f"Python/CLI {fresh_ratio:.4f} ({100 * (fresh_ratio - 1):+.2f} %)")
        print(f"end to end (median): CLI {median(rows, 2):.4f} s, Python {median(rows, 3):.4f} s, "
              f"Python/CLI {total_ratio:.4f} ({100 * (total_ratio - 1):+.2f} %)")
        cpu_ratio = statistics.median(r[5] / r[4] for r in rows)
        print(f"CPU time end to end (median): CLI {median(rows, 4):.4f} s, Python {median(rows, 5):.4f} s, "
              f"Python/CLI {cpu_ratio:.4f} ({100 * (cpu_ratio - 1):+.2f} %)")
        start = startup_cpu(cli, args.repeat)
        net = statistics.median(r[5] / (r[4] - start) for r in rows)
        print(f"CPU of starting the command (`otmpm --version`, median): {start:.4f} s; "
              f"Python / (CLI - start) {net:.4f} ({100 * (net - 1):+.2f} %)")
        print(f"2. sim.step() overhead: one-particle scene, {args.steps} steps, {args.repeat} interleaved repetitions")
        rows = step_overhead(args.build, args.steps, args.repeat, work)
        py, mod, cxx = median(rows, 0), median(rows, 1), median(rows, 2)
        print(f"ns per step (median): Python loop {py:.0f}, sim.step(n) {mod:.0f}, C++ program {cxx:.0f}; "
              f"(min): {min(r[0] for r in rows):.0f}, {min(r[1] for r in rows):.0f}, {min(r[2] for r in rows):.0f}")
        for name, i in (("sim.step(n)", 1), ("the C++ program", 2)):
            diff = [(r[0] - r[i]) / 1000 for r in rows]
            print(f"overhead of a Python call per step vs {name}: median {statistics.median(diff):.3f} us "
                  f"(per-repetition differences from {min(diff):.3f} to {max(diff):.3f} us); "
                  f"difference of the minima {(min(r[0] for r in rows) - min(r[i] for r in rows)) / 1000:.3f} us")


if __name__ == "__main__":
    main()
