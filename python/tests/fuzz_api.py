#!/usr/bin/env python3
"""Fuzzes the Python API of otmpm: random call sequences on Scene, Simulation
(with its views), otmpm.results and otmpm.basis objects - random lifetimes
(objects dropped early, `with` blocks left by exceptions), call orders (every
method after finish(), after t_end, after an instability) and argument types
(numbers out of range, NaN, strings with control characters, containers that
contain themselves, paths to FIFOs and directories, damaged result files).

Each call is checked against what docs/python.md and docs/stability.md
("What the Python package guarantees") promise: it returns, or raises one of
the exception types documented for that call in that state - anything else,
a crash or a call running longer than CALL_SECONDS is a finding. After each
run the result file must read back with a final status (never "running") and
no otmpm lock file or undo journal may be left.

    python3 fuzz_api.py [--seed N] [--iterations N | --seconds S] [--workdir DIR]

Prints each call before making it (so a crash shows the last one), and exits
1 with the call, the exception and the seed on a finding. Run by
python/tests/test_fuzz.py (a fixed seed) and scripts/fuzz.sh (a new seed).
"""
import argparse
import faulthandler
import gc
import math
import os
import random
import shutil
import sys
import tempfile
import time
import warnings

import numpy as np

import otmpm
import otmpm.basis
import otmpm.results

#: Longest time one call may take (the scenes are tiny): a longer one is a hang.
CALL_SECONDS = 30
SOURCE = os.environ.get("OTMPM_SOURCE_DIR", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
DYKA = os.path.join(SOURCE, "examples", "dyka.toml")
#: A short, cheap base scene (1D, linear basis, 80 particles, ~40 steps).
BASE = {"simulation.t_end": 4e-6, "output.every": 1e-6, "basis.kind": "linear", "simulation.integrator": "musl"}


class Finding(Exception):
    """A call whose outcome is not a documented one."""


def text(value, limit=120):
    """repr() cut for the log (the type alone for a value nested too deep to repr)."""
    try:
        r = repr(value)
    except RecursionError:
        return f"<a deeply nested {type(value).__name__}>"
    return r if len(r) <= limit else r[:limit] + f"...({len(r)} chars)"


class Fuzzer:
    def __init__(self, seed, workdir):
        self.rng = random.Random(seed)
        self.seed = seed
        self.workdir = workdir
        self.calls = 0
        self.outcomes = {}  # result or exception type name -> count
        self.base = otmpm.Scene.from_toml(DYKA, BASE)
        self.counter = 0
        os.mkfifo(os.path.join(workdir, "fifo.h5"))
        os.mkfifo(os.path.join(workdir, "fifo.toml"))
        os.makedirs(os.path.join(workdir, "folder.h5"))

    # ---------------------------------------------------------------- values

    def number(self):
        return self.rng.choice([0, 1, -1, 2, 3, 7, 100, 2**31, 2**63, -(2**63), 10**400, 0.0, -0.0, 0.5, 1e-300,
                                1e300, -1e300, math.inf, -math.inf, math.nan, 4e-6, 1e-6, 2.7,
                                np.float32(1.5), np.int64(3), np.float64(math.nan)])

    def string(self):
        return self.rng.choice(["", "x", "fe", "lme", "linear", "mpm", "ul", "a\x00b", "new\nline", "tab\t", "c:d",
                                "\u00e9\U0001F600", "n" * 10_000, "--", "&<>\"'", "../up", "/", ".", " space "])

    def value(self, depth=0):
        kind = self.rng.randrange(9 if depth < 3 else 5)
        if kind < 2:
            return self.number()
        if kind == 2:
            return self.string()
        if kind == 3:
            return self.rng.choice([None, True, False, b"bytes", object(), np.array([1.0, 2.0]), np.zeros((2, 2))])
        if kind == 4:
            return self.rng.choice([[0.0], [1.0, 2.0], [], ["x", "v"], [True]])
        if kind in (5, 6):
            return [self.value(depth + 1) for _ in range(self.rng.randrange(4))]
        if kind == 7:
            return {self.string(): self.value(depth + 1) for _ in range(self.rng.randrange(3))}
        cyclic = [1.0]
        cyclic.append(cyclic)
        return self.rng.choice([cyclic, self.deep()])

    def deep(self):
        x = [0.0]
        for _ in range(self.rng.choice([10, 300, 5000])):
            x = [x]
        return x

    def key(self):
        keys = ["simulation.t_end", "simulation.cfl", "simulation.dt", "simulation.integrator", "simulation.mode",
                "basis.kind", "grid.cells", "grid.lower", "material.steel.young", "material.0.density",
                "body.bar.velocity", "output.every", "output.fields", "output.format", "output.file",
                "output.checkpoint_every", "output.checkpoint_file", "output.precision", "simulation.unknown",
                "nothing", "body.9.name", "material.steel.name", ""]
        return self.rng.choice(keys + [self.string()])

    def overrides(self):
        if self.rng.random() < 0.2:
            return [self.rng.choice([f"{self.key()}={self.string()}", "no_equals", "simulation.cfl=0.2\nx=1", ""])
                    for _ in range(self.rng.randrange(3))]
        if self.rng.random() < 0.1:
            return self.value()
        odd_key = self.rng.random() < 0.05  # keys must be strings: TypeError
        return {(self.rng.choice([5, None, (1, 2)]) if odd_key else self.key()): self.value()
                for _ in range(self.rng.randrange(4))}

    def out_path(self):
        self.counter += 1
        if self.rng.random() < 0.6:
            return os.path.join(self.workdir, self.rng.choice([f"r{self.counter}.h5", f"run--{self.counter} &<>.h5"]))
        name = self.rng.choice([f"r{self.counter}", f"ctl\x01{self.counter}.h5", f"c:{self.counter}.h5", "fifo.h5",
                                "folder.h5", f"missing/r{self.counter}.h5", f"r{self.counter}.png",
                                f"r{self.counter}.xdmf"])
        return self.rng.choice([os.path.join(self.workdir, name), None, 5, b"bytes.h5"])

    # ---------------------------------------------------------------- calls

    def call(self, what, f, *allowed):
        """Calls f(); returns (result, None) or (None, exception) for an allowed exception type."""
        self.calls += 1
        print(f"[{self.calls}] {what}", end="", flush=True)
        faulthandler.dump_traceback_later(CALL_SECONDS, exit=True)
        try:
            result = f()
            print(" ->", type(result).__name__)
            self.outcomes[type(result).__name__] = self.outcomes.get(type(result).__name__, 0) + 1
            return result, None
        except allowed as e:
            print(" ->", type(e).__name__)
            self.outcomes[type(e).__name__] = self.outcomes.get(type(e).__name__, 0) + 1
            return None, e
        except Exception as e:
            raise Finding(f"{what}: {type(e).__name__}: {text(str(e), 400)} (allowed: "
                          f"{', '.join(a.__name__ for a in allowed) or 'none'})") from e
        finally:
            faulthandler.cancel_dump_traceback_later()

    def scene(self):
        """A random scene: the base one, or one with random overrides (the base one when they are refused)."""
        if self.rng.random() < 0.5:
            return self.base
        s, _ = self.call("Scene.with_overrides", lambda: self.base.with_overrides(self.overrides()), otmpm.InputError,
                         TypeError)
        return self.base if s is None else s

    # ---------------------------------------------------------------- scenes

    def scenes(self):
        for _ in range(self.rng.randrange(1, 6)):
            op = self.rng.randrange(5)
            if op == 0:
                path = self.rng.choice([DYKA, os.path.join(self.workdir, "fifo.toml"), self.workdir,
                                        os.path.join(self.workdir, "missing.toml"), 3, None])
                self.call(f"Scene.from_toml({text(path)})", lambda: otmpm.Scene.from_toml(path, self.overrides()),
                          otmpm.InputError, TypeError)
            elif op == 1:
                d = self.base.to_dict(full=self.rng.random() < 0.5)
                section = self.rng.choice(list(d))
                target = d[section][0] if isinstance(d[section], list) else d[section]
                target[self.string()] = self.value()
                if self.rng.random() < 0.3:
                    target["self"] = d
                self.call("Scene.from_dict", lambda: otmpm.Scene.from_dict(d, name=self.string()), otmpm.InputError,
                          TypeError)
            elif op == 2:
                self.call("Scene.from_dict(value)", lambda: otmpm.Scene.from_dict(self.value()), otmpm.InputError,
                          TypeError)
            else:
                s = self.scene()
                full = self.rng.random() < 0.5
                back, _ = self.call("Scene.from_dict(to_dict())", lambda: otmpm.Scene.from_dict(s.to_dict(full)))
                if back.to_toml(full) != s.to_toml(full):
                    raise Finding("Scene.from_dict(scene.to_dict()) is not the same scene")

    # ---------------------------------------------------------------- simulations

    def simulation(self):
        scene = self.scene()
        out = self.out_path()
        threads = self.rng.choice([None, 1, 2, 0, -1])
        callback = self.rng.choice([None, None, lambda s: None, self.raising_callback])
        force = self.rng.random() < 0.5
        sim, error = self.call(f"Simulation(out={text(out)}, threads={threads})",
                               lambda: otmpm.Simulation(scene, out=out, threads=threads, callback=callback,
                                                        force=force, write_results=self.rng.random() < 0.9),
                               otmpm.InputError, TypeError, ValueError, OSError)
        if sim is None:
            return
        path = out if isinstance(out, str) else (scene.output_file if out is None else None)
        closed = False
        for _ in range(self.rng.randrange(1, 16)):
            if self.rng.random() < 0.05:
                break  # dropped unfinished
            closed = self.simulation_call(sim, closed)
        if self.rng.random() < 0.5 and not closed:
            self.call("Simulation.finish (last)", sim.finish)
        del sim
        gc.collect()
        if path and os.path.isfile(path) and sim_wrote(path):
            self.check_result(path)

    def raising_callback(self, sim):
        if self.rng.random() < 0.3:
            raise KeyError("raised by the callback")

    def simulation_call(self, sim, closed):
        """One random call on a simulation; returns whether finish() has run."""
        # step, advance_to, write_frame, interrupt, finish, particles, nodes, properties, callback, with, poke v
        op = self.rng.choices(range(11), weights=[25, 15, 10, 4, 4, 12, 4, 8, 5, 4, 6])[0]
        finished = sim.finished
        runtime = (RuntimeError,) if closed else ()
        # A step may become unstable (NaN written into v), meet the callback's KeyError or an output error.
        stepping = (otmpm.InstabilityError, KeyError, OSError)
        if op == 0:
            n = self.rng.choice([1, 3, 10, 100] * 4 + [0, -1, 2**63, 2.5, "x", None])
            int_n = isinstance(n, int)
            allowed = runtime + stepping + ((RuntimeError,) if finished else ()) + \
                ((ValueError,) if int_n and n < 0 else ()) + ((TypeError,) if not int_n or n >= 2**63 else ())
            self.call(f"step({text(n)})", lambda: sim.step(n), *allowed)
        elif op == 1:
            # Targets at most 100 steps ahead (t_end only when it is that near): a run never takes minutes.
            near = sim.next_dt > 0 and (sim.t_end - sim.t) / sim.next_dt < 100
            t = self.rng.choice([sim.t + sim.next_dt * self.rng.choice([1, 10, 100]), -1.0, math.nan, "x"] +
                                ([sim.t_end, math.inf, 1.0] if near else []))
            self.call(f"advance_to({t})", lambda: sim.advance_to(t),
                      *(runtime + stepping + ((TypeError,) if t == "x" else ())))
        elif op == 2:
            self.call("write_frame", sim.write_frame, *(runtime + (otmpm.InstabilityError, OSError)))
        elif op == 3:
            self.call("interrupt", sim.interrupt, *(runtime + ((RuntimeError,) if finished else ()) + (OSError,)))
        elif op == 4:
            summary, _ = self.call("finish", sim.finish, *runtime)
            if summary is not None:
                if summary.status == "running" or summary.exit_code not in (0, 1, 4, 130):
                    raise Finding(f"finish: summary status {summary.status!r}, exit code {summary.exit_code}")
                return True
            return closed
        elif op == 5:
            field = self.rng.choice(["x", "X", "v", "a", "stress", "stress_zz", "strain", "F", "volume", "mass",
                                     "density", "material", "body", "state"])
            self.call(f"particles.{field}", lambda: getattr(sim.particles, field))
        elif op == 6:
            field = self.rng.choice(["x", "v", "m"])
            self.call(f"nodes.{field}", lambda: getattr(sim.nodes, field))
        elif op == 7:
            for name in ("t", "dt", "next_dt", "steps", "t_end", "finished", "status", "dimension", "scene"):
                self.call(name, lambda: getattr(sim, name))
            self.call("energy", sim.energy)
        elif op == 8:
            value = self.rng.choice([None, lambda s: None, 3, self.raising_callback])
            self.call(f"callback = {text(value)}", lambda: setattr(sim, "callback", value),
                      *((TypeError,) if value == 3 else ()))
        elif op == 10:
            v, _ = self.call("particles.v", lambda: sim.particles.v)
            value = self.rng.choice([math.nan, math.inf, 1e300, 0.0, -5.0])
            self.call(f"particles.v[...] = {value}", lambda: v.__setitem__(self.rng.randrange(len(v)), value))
        else:
            def leave_by_exception():
                with sim:
                    raise KeyError("leaves the with block")
            self.call("with sim: raise", leave_by_exception, KeyError, *runtime)
            return True
        return closed

    def check_result(self, path):
        """A finished or dropped run's file: readable, a final status, no lock file."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r, _ = self.call(f"results.open({text(path)})", lambda: otmpm.results.open(path))
        with r:
            if r.status in (None, "running"):
                raise Finding(f"{path}: status {r.status!r} after the run ended")
        folder = os.path.dirname(path) or "."
        locks = [n for n in os.listdir(folder) if n.endswith((".otmpm-lock", ".otmpm-undo"))]
        if locks:
            raise Finding(f"lock files or undo journals left after the run ended: {locks}")

    # ---------------------------------------------------------------- results

    def results(self):
        good = os.path.join(self.workdir, "good.h5")
        if not os.path.exists(good):
            self.call("run", lambda: otmpm.run(self.base, out=good))
        path = self.rng.choice([good, self.damaged(good), os.path.join(self.workdir, "fifo.h5"),
                                os.path.join(self.workdir, "folder.h5"), os.path.join(self.workdir, "nothing.h5"),
                                DYKA])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r, _ = self.call(f"results.open({text(path)})", lambda: otmpm.results.open(path), OSError)
            if r is None:
                return
            with r:
                for _ in range(self.rng.randrange(1, 5)):
                    name = self.rng.choice(["x", "v", "stress", "nothing", "x3", 5])
                    self.call(f"field({name!r})", lambda: r.field(name), KeyError, OSError, TypeError)
                self.call("probes, energy, scene", lambda: (r.probes, r.energy, r.scene, r.errors, r.times),
                          OSError, ValueError)

    def damaged(self, good):
        """A copy of `good` cut short, or with a block zeroed or inverted."""
        data = bytearray(open(good, "rb").read())
        at = self.rng.randrange(len(data))
        kind = self.rng.choice(["cut", "zero", "flip"])
        if kind == "cut":
            data = data[:at]
        else:
            for i in range(at, min(at + 16, len(data))):
                data[i] = 0 if kind == "zero" else data[i] ^ 0xFF
        path = os.path.join(self.workdir, f"damaged_{kind}_{at}.h5")
        with open(path, "wb") as f:
            f.write(data)
        return path

    # ---------------------------------------------------------------- basis

    def basis(self):
        dim = self.rng.choice([1, 2, 3])
        def pick(usual):
            return self.value() if self.rng.random() < 0.2 else usual

        lower = pick([0.0] * dim)
        upper = pick([1.0] * dim)
        cells = pick([self.rng.choice([1, 4, 2.0, 2.7, 0, -3, 10**9])] * dim)
        grid = otmpm.basis.Grid(lower, upper, cells, perturbation=self.rng.choice([0.0, 0.2, -1, math.nan, 0.5]),
                                seed=self.rng.choice([1, -1, 2**40]))
        nodes = grid if self.rng.random() < 0.8 else pick(np.random.default_rng(1).uniform(0, 1, (30, dim)))
        kind = self.rng.choice(list(otmpm.basis.KINDS) + ["nothing", 3])
        options = {}
        if self.rng.random() < 0.3:
            options[self.rng.choice(["gamma_lme", "tolerance", "newton_tolerance", "max_newton_iterations", "d_max",
                                     "ppc"])] = self.number()
        h = self.rng.choice([None, 0.1, -1.0, math.nan])
        b, _ = self.call(f"Basis({kind!r}, {text(nodes)}, h={h}, {text(options)})",
                         lambda: otmpm.basis.Basis(kind, nodes, h, **options), otmpm.InputError, TypeError,
                         otmpm.BasisError)
        if b is None:
            return
        points = self.rng.choice([np.random.default_rng(2).uniform(0, 1, (5, dim)), [[math.nan] * dim], [[5.0] * dim],
                                  [], "x", [[0.5] * (dim + 1)]])
        self.call(f"evaluate({text(points)})", lambda: b.evaluate(points), otmpm.BasisError, otmpm.InputError,
                  ValueError)

    # ---------------------------------------------------------------- loop

    def iteration(self):
        self.rng.choice([self.scenes, self.simulation, self.simulation, self.results, self.basis])()


def sim_wrote(path):
    """True when `path` is a result file a Simulation of this fuzzer wrote (HDF5, not a FIFO)."""
    return os.path.isfile(path) and open(path, "rb").read(8) == b"\x89HDF\r\n\x1a\n"


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seed", type=int, default=int(time.time()))
    p.add_argument("--iterations", type=int, default=0)
    p.add_argument("--seconds", type=float, default=0)
    p.add_argument("--workdir")
    a = p.parse_args()
    faulthandler.enable()
    workdir = os.path.abspath(a.workdir or tempfile.mkdtemp(prefix="otmpm_fuzz_api_"))
    os.makedirs(workdir, exist_ok=True)
    os.chdir(workdir)  # relative result paths (a scene's output.file) land here
    fuzzer = Fuzzer(a.seed, workdir)
    end = time.monotonic() + a.seconds
    done = 0
    try:
        while (a.iterations and done < a.iterations) or (a.seconds and time.monotonic() < end):
            fuzzer.iteration()
            done += 1
    except Finding as e:
        print(f"FINDING (seed {a.seed}, iteration {done}, call {fuzzer.calls}): {e}", file=sys.stderr)
        sys.exit(1)
    finally:
        if not a.workdir:
            shutil.rmtree(workdir, ignore_errors=True)
    outcomes = ", ".join(f"{k} {v}" for k, v in sorted(fuzzer.outcomes.items(), key=lambda kv: -kv[1]))
    print(f"fuzz_api: no finding in {done} iterations, {fuzzer.calls} calls (seed {a.seed}); outcomes: {outcomes}")


if __name__ == "__main__":
    main()
