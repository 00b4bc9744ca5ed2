"""otmpm.run: the command line's run from Python - the same results to the
last bit, the GIL released while it runs, Ctrl-C leaving a valid file."""
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time

import h5py
import numpy as np
import pytest

import otmpm
from conftest import example, run_cli

DYKA = example("dyka/dyka_n40.toml")


def attrs(path):
    with h5py.File(path, "r") as f:
        return {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()}


def last_frame(path):
    with h5py.File(path, "r") as f:
        frames = f["frames"]
        g = frames[sorted(frames)[-1]]
        return {name: g[name][()] for name in g}


def test_dyka_errors_equal_the_command_lines_to_the_last_bit(tmp_path):
    cli_out, py_out = tmp_path / "cli.h5", tmp_path / "py.h5"
    done = run_cli("run", DYKA, "--out", cli_out, "--quiet")
    assert done.returncode == 0, done.stderr
    s = otmpm.run(otmpm.Scene.from_toml(DYKA), out=str(py_out))
    cli = attrs(cli_out)
    assert set(s.errors) == {"rms_velocity_error", "rms_displacement_error", "rms_stress_error", "history_error_A"}
    for name, value in s.errors.items():
        assert value == cli[name], name  # bitwise: == on doubles
    assert s.max_energy_ratio == cli["max_energy_ratio"] and s.energy_drift == cli["energy_drift"]
    assert (s.steps, s.time, s.status, s.exit_code) == (cli["steps"], cli["t_end"], "ok", 0)
    # The whole result file has the same content, timings and the random run id apart.
    py = attrs(py_out)
    # (seconds_output_thread: only `otmpm run` writes on a writer thread)
    timing = {k for k in {**py, **cli} if k.startswith("seconds_") or k in ("wall_seconds", "run_id")}
    assert {k: v for k, v in py.items() if k not in timing} == {k: v for k, v in cli.items() if k not in timing}
    a, b = last_frame(cli_out), last_frame(py_out)
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


def test_summary_is_dict_like(tmp_path):
    s = otmpm.run(otmpm.Scene.from_toml(DYKA, {"simulation.t_end": 1e-5}), out=str(tmp_path / "r.h5"))
    assert s["steps"] == s.steps and dict(s)["status"] == "ok" and "wall_seconds" in s
    assert s.out_file == str(tmp_path / "r.h5") and s.particles == 80 and s.nodes == 43
    assert str(s).startswith("ok: mpm npc lme: ") and "rms_velocity_error = " in str(s)
    assert set(s.phases) == {"basis", "to_nodes", "nodal_update", "to_particles", "constitutive", "output"}
    with pytest.raises(AttributeError):
        s.no_such_key


def test_summary_reports_the_node_resets_of_a_ul_run(tmp_path):
    # The quarter Taylor bar at h = R/2 for 10 us: ul mode lays its nodes out anew twice.
    grid = {"body.bar.file": "taylor_bar/quarter_h1.6.csv", "grid.lower": [0, 0, -0.0032],
            "grid.upper": [0.0144, 0.0144, 0.0368], "grid.cells": [9, 9, 25], "simulation.t_end": 1e-5}
    ul = otmpm.run(otmpm.Scene.from_toml(example("taylor_bar.toml"), {**grid, "simulation.mode": "ul"}),
                   out=str(tmp_path / "ul.h5"))
    assert ul.exit_code == 0 and ul.diagnostics["node_resets"] >= 1
    assert attrs(tmp_path / "ul.h5")["node_resets"] == ul.diagnostics["node_resets"]
    assert f"node_resets = {ul.diagnostics['node_resets']:.0f}" in str(ul)
    mpm = otmpm.run(otmpm.Scene.from_toml(example("taylor_bar.toml"), grid), write_results=False)
    assert mpm.exit_code == 0 and dict(mpm.diagnostics) == {}


def test_unstable_run_reports_exit_code_1(tmp_path):
    s = otmpm.run(otmpm.Scene.from_toml(DYKA, {"simulation.cfl": 4.0}), out=str(tmp_path / "u.h5"))
    assert s.exit_code == 1 and s.status.startswith("unstable: ")
    assert attrs(tmp_path / "u.h5")["status"] == s.status


def test_results_do_not_depend_on_threads():
    scene = otmpm.Scene.from_toml(example("dyka/dyka_n1333.toml"), {"simulation.t_end": 2e-6})
    one = otmpm.run(scene, threads=1, write_results=False)
    two = otmpm.run(scene, threads=2, write_results=False)
    assert one.particles > 2 * 512  # enough particles for two threads
    assert one.errors == two.errors and one.steps == two.steps
    with pytest.raises(ValueError, match="threads must be >= 1"):
        otmpm.run(scene, threads=0)


def test_run_releases_the_gil():
    """While run() works in a thread, the main thread keeps running Python code."""
    scene = otmpm.Scene.from_toml(example("dyka/dyka_n133.toml"))
    worker = threading.Thread(target=otmpm.run, args=(scene,), kwargs={"write_results": False})
    ticks = []
    worker.start()
    while worker.is_alive():
        ticks.append(time.perf_counter())
        time.sleep(0.001)
    worker.join()
    gaps = np.diff(ticks)
    assert len(ticks) > 20 and gaps.max() < 0.2, (len(ticks), gaps.max())


def ctrl_c_child(*args):
    """A Python child that Ctrl-C reaches: SIGINT at its default in the child
    (Python then installs its KeyboardInterrupt handler), whatever this test
    inherited - a shell's background job (`cmd &` without job control, as a
    CI runner may start it) ignores SIGINT, and an ignored signal stays
    ignored across exec."""
    return subprocess.Popen([sys.executable, "-c", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


CHILD = textwrap.dedent("""
    import sys, otmpm
    scene = otmpm.Scene.from_toml(sys.argv[1], {"simulation.t_end": 100.0, "output.every": 0.01})
    print("running", flush=True)
    try:
        otmpm.run(scene, out=sys.argv[2])
    except KeyboardInterrupt:
        print("KeyboardInterrupt", flush=True)
        sys.exit(130)
    print("finished", flush=True)
""")


# A body of 3.6e5 particles and one over it of 5.2e7 seeds that the first
# body's overlap drops: its seeding takes seconds (measured 8.5 s), and
# holds no more than the first body's particles.
SLOW_SETUP = """
[simulation]
dimension = 2
integrator = "musl"
t_end = 1e-4
[basis]
kind = "linear"
[grid]
lower = [0.0, 0.0]
upper = [1.0, 1.0]
cells = [1000, 1000]
[[material]]
name = "m"
model = "linear_elastic"
density = 1000.0
young = 1.0e6
poisson = 0.3
[[body]]
name = "a"
material = "m"
lower = [0.2, 0.2]
upper = [0.8, 0.8]
particles_per_cell = 1
[[body]]
name = "b"
material = "m"
lower = [0.2, 0.2]
upper = [0.8, 0.8]
particles_per_cell = 12
overlap = "first"
[output]
every = 1e-4
"""

SETUP_CHILD = textwrap.dedent("""
    import sys, time, otmpm
    scene = otmpm.Scene.from_toml(sys.argv[1])
    print("building", flush=True)
    start = time.perf_counter()
    try:
        sim = otmpm.Simulation(scene, out=sys.argv[2])
    except KeyboardInterrupt:
        print("KeyboardInterrupt", flush=True)
        sys.exit(130)
    print("built", time.perf_counter() - start, flush=True)
""")


def test_ctrl_c_during_the_set_up_raises_keyboard_interrupt_at_once_and_writes_nothing(tmp_path):
    """Ctrl-C while a Simulation seeds its bodies: KeyboardInterrupt within
    a row of cells (before, only after the whole set-up), no object, no file."""
    scene = tmp_path / "slow.toml"
    scene.write_text(SLOW_SETUP)
    out = tmp_path / "r.h5"
    child = ctrl_c_child(SETUP_CHILD, str(scene), str(out))
    assert child.stdout.readline().strip() == "building"
    time.sleep(1.0)  # seeding (measured 8.5 s in all)
    sent = time.perf_counter()
    child.send_signal(signal.SIGINT)
    stdout, stderr = child.communicate(timeout=60)
    assert child.returncode == 130, (stdout, stderr)
    assert stdout.strip() == "KeyboardInterrupt"
    assert time.perf_counter() - sent < 3.0  # measured 0.15 s; the set-up takes seconds more
    assert not out.exists() and not (tmp_path / "r.xdmf").exists()
    assert not [n for n in os.listdir(tmp_path) if n.endswith(".otmpm-lock")]


def test_ctrl_c_raises_keyboard_interrupt_and_leaves_a_valid_file(tmp_path):
    out = tmp_path / "interrupted.h5"
    child = ctrl_c_child(CHILD, example("fixed_bar.toml"), str(out))
    assert child.stdout.readline().strip() == "running"
    time.sleep(1.0)  # the run is under way (its t_end is minutes away)
    sent = time.perf_counter()
    child.send_signal(signal.SIGINT)
    stdout, stderr = child.communicate(timeout=60)
    assert child.returncode == 130, stderr
    assert stdout.strip() == "KeyboardInterrupt"
    assert time.perf_counter() - sent < 5.0
    with otmpm.results.open(out) as r:
        assert r.status == "interrupted"
        assert 0 < r.attrs["steps"] and 0 < r.attrs["t_end"] < 100.0
        assert len(r.frames) >= 1 and np.isfinite(r.frames[-1]["x"]).all()


def test_force_replaces_an_existing_result_file(tmp_path):
    out = tmp_path / "again.h5"
    out.write_text("not a result file\n")  # a stale file in the way
    scene = otmpm.Scene.from_toml(DYKA, {"simulation.t_end": 1e-5})
    s = otmpm.run(scene, out=str(out), force=True)
    assert s.status == "ok" and not s.interrupted
    assert attrs(out)["status"] == "ok" and attrs(out)["steps"] == s.steps
    with otmpm.Simulation(scene, out=str(out), force=True) as sim:  # the same option when stepping by hand
        sim.step(2)
    assert attrs(out)["steps"] == 2
    runs = otmpm.pair(scene.with_overrides({"output.file": str(tmp_path / "p.h5")}), force=True)
    assert {m: r.status for m, r in runs.items()} == {"mpm": "ok", "ul": "ok"}
