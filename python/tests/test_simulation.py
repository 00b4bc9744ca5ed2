"""otmpm.Simulation: stepping by hand, NumPy views of the engine's arrays
(no copy, valid for the whole run), the per-step callback, frames."""
import h5py
import numpy as np
import pytest

import otmpm
from conftest import example

DYKA = example("dyka/dyka_n40.toml")
SHORT = {"simulation.t_end": 2e-5, "output.every": 5e-6}


def short_dyka(**extra):
    return otmpm.Scene.from_toml(DYKA, {**SHORT, **extra})


def final_frame(path):
    with h5py.File(path, "r") as f:
        g = f["frames"][sorted(f["frames"])[-1]]
        return {name: g[name][()] for name in g}


def test_views_alias_engine_memory_and_follow_the_steps():
    sim = otmpm.Simulation(short_dyka(), write_results=False)
    x, v = sim.particles.x, sim.particles.v
    assert x.base is sim and not x.flags.owndata  # a view, kept alive by the simulation
    assert np.shares_memory(x, sim.particles.x) and np.shares_memory(v, sim.particles.v)
    address = x.__array_interface__["data"][0]
    before = x.copy()
    sim.step(10)
    assert sim.particles.x.__array_interface__["data"][0] == address  # no reallocation
    assert not np.array_equal(x, before)  # the old view shows the new state
    assert np.array_equal(x, sim.particles.x)
    assert x.shape == (80, 1) and sim.particles.stress.shape == (80, 1, 1) and sim.particles.mass.shape == (80,)


def test_view_memory_is_the_engines_across_the_whole_run():
    """Every view keeps its address from the first step to t_end (mpm and ul, npc and otm)."""
    for overrides in ({}, {"simulation.mode": "ul"}, {"simulation.mode": "ul", "simulation.integrator": "otm"}):
        sim = otmpm.Simulation(short_dyka(**overrides), write_results=False)
        p, n = sim.particles, sim.nodes
        views = [p.x, p.X, p.v, p.stress, p.strain, p.volume, p.mass, p.density, n.x, n.v, n.m]
        views += [a for a in (p.a, p.F) if a is not None]
        addresses = [a.__array_interface__["data"][0] for a in views]
        nodes_before = n.x.copy()
        sim.advance_to(sim.t_end)
        again = [p.x, p.X, p.v, p.stress, p.strain, p.volume, p.mass, p.density, n.x, n.v, n.m]
        again += [a for a in (p.a, p.F) if a is not None]
        assert [a.__array_interface__["data"][0] for a in again] == addresses, overrides
        assert np.array_equal(n.x, nodes_before) == (sim.scene.mode == "mpm")  # ul advects the nodes


def test_stepping_by_hand_equals_run_bitwise(tmp_path):
    scene = short_dyka()
    whole = otmpm.run(scene, out=str(tmp_path / "run.h5"))
    sim = otmpm.Simulation(scene, out=str(tmp_path / "hand.h5"))
    for _ in range(whole.steps):
        sim.step()
    assert sim.finished and sim.t == whole.time
    frame = final_frame(tmp_path / "run.h5")
    assert np.array_equal(sim.particles.x, frame["x"]) and np.array_equal(sim.particles.v, frame["v"])
    assert np.array_equal(sim.particles.stress.reshape(-1, 1), frame["stress"])
    by_hand = sim.finish()
    assert by_hand.errors == whole.errors and by_hand.steps == whole.steps
    assert by_hand.max_energy_ratio == whole.max_energy_ratio


def test_tensor_views_have_the_engines_component_order(tmp_path):
    """F[p, i, j] = F_ij, checked on a deforming 2D plate (F not symmetric) against the
    result file, which stores tensors row by row."""
    scene = otmpm.Scene.from_toml(example("plate_impact.toml"), {
        "output.fields": ["x", "stress", "F"], "output.every": 0.0, "grid.cells": [29, 27]})
    sim = otmpm.Simulation(scene, out=str(tmp_path / "plate.h5"))
    sim.step(20)
    F = sim.particles.F
    assert F.shape == (len(sim.particles), 2, 2) and F.strides == (32, 8, 16)
    assert np.abs(F[:, 0, 1] - F[:, 1, 0]).max() > 1e-6  # not symmetric: a transposed view would show
    sim.write_frame()
    sim.finish()  # closes the result file (a build with MPI keeps it open while the run goes)
    frame = final_frame(tmp_path / "plate.h5")  # the frame just written
    n = len(sim.particles)
    assert np.array_equal(frame["F"], F.reshape(n, 4)) and np.array_equal(frame["stress"], sim.particles.stress.reshape(n, 4))


def test_views_are_read_only_except_v():
    sim = otmpm.Simulation(short_dyka(), write_results=False)
    p = sim.particles
    for name in ("x", "X", "stress", "strain", "volume", "mass", "density", "material", "body"):
        with pytest.raises(ValueError, match="read-only"):
            getattr(p, name)[0] = 0
    for a in (sim.nodes.x, sim.nodes.v, sim.nodes.m):
        assert not a.flags.writeable
    assert p.v.flags.writeable
    assert p.F is None  # small strain in mpm mode: no deformation gradient
    assert p.stress_zz is None  # 1D: no plane strain
    assert p.state == {}  # linear_elastic has no internal variables


def test_pic_relaxation_books_what_it_takes_from_noise_written_into_v(tmp_path):
    """v written from Python with particle-to-particle noise: the PIC relaxation
    (pic_relaxation_time) takes part of it and books it as energy()["relaxation"]
    and in the result file's /energy/relaxation."""
    sim = otmpm.Simulation(short_dyka(**{"simulation.pic_relaxation_time": 1e-6}), out=str(tmp_path / "pic.h5"))
    sim.particles.v[::2] += 1.0  # FLIP would keep this noise
    sim.particles.v[1::2] -= 1.0
    sim.step(20)
    E = sim.energy()
    assert E["relaxation"] > 0.1 * E["kinetic"]
    sim.advance_to(1.0)  # to t_end, where the last output is written
    sim.finish()
    with h5py.File(tmp_path / "pic.h5", "r") as f:
        assert f["energy"]["relaxation"][-1] == pytest.approx(sim.energy()["relaxation"], rel=1e-12)
        assert f["energy"]["relaxation"][-1] >= E["relaxation"] > 0.0


def test_writing_v_changes_the_next_step():
    a = otmpm.Simulation(short_dyka(), write_results=False)
    b = otmpm.Simulation(short_dyka(), write_results=False)
    b.particles.v[:] = 0.0  # the bar at rest: nothing moves
    a.step(5)
    b.step(5)
    assert np.abs(b.particles.v).max() == 0.0 and np.abs(a.particles.v).max() > 1.0
    assert np.array_equal(b.particles.x, b.particles.X)


@pytest.mark.parametrize("overrides", [{}, {"basis.kind": "linear", "simulation.integrator": "fe"},
                                       {"simulation.mode": "ul"}, {"simulation.integrator": "musl"}],
                         ids=["mpm-npc-lme", "mpm-fe-linear", "ul-npc-lme", "mpm-musl-lme"])
def test_nan_written_into_v_is_an_instability_at_the_next_step(tmp_path, overrides):
    out = tmp_path / "nan.h5"
    sim = otmpm.Simulation(short_dyka(**overrides), out=str(out))
    sim.step(3)
    sim.particles.v[7, 0] = np.nan
    with pytest.raises(otmpm.InstabilityError) as info:
        sim.step()
    assert sim.finished and sim.status == "unstable: " + str(info.value)
    summary = sim.finish()
    assert summary.exit_code == 1 and summary.steps == 3
    with otmpm.results.open(out) as r:
        assert r.status == summary.status and len(r.frames) >= 1


def test_callback_runs_after_every_step():
    seen = []
    sim = otmpm.Simulation(short_dyka(), write_results=False,
                           callback=lambda s: seen.append((s.steps, float(np.abs(s.particles.v).max()))))
    sim.step()
    sim.step(4)
    sim.advance_to(1e-5)
    assert [k for k, _ in seen] == list(range(1, sim.steps + 1))
    sim.callback = None
    sim.step(2)
    assert len(seen) == sim.steps - 2


def test_callback_exception_stops_the_loop_between_steps():
    def stop_at_7(s):
        if s.steps == 7:
            raise RuntimeError("enough")
    sim = otmpm.Simulation(short_dyka(), write_results=False, callback=stop_at_7)
    with pytest.raises(RuntimeError, match="enough"):
        sim.advance_to(sim.t_end)
    assert sim.steps == 7 and not sim.finished
    sim.callback = None
    sim.step()  # the run goes on
    assert sim.steps == 8


def test_advance_to_dt_and_energy():
    sim = otmpm.Simulation(short_dyka(), write_results=False)
    assert sim.dt == 0.0 and sim.t == 0.0 and sim.steps == 0
    planned = sim.next_dt
    sim.step()
    assert sim.dt == planned and sim.t == planned
    sim.advance_to(1e-5)
    assert 1e-5 * (1 - 1e-9) <= sim.t < 1e-5 + sim.dt
    E = sim.energy()
    assert E["total"] == E["kinetic"] + E["strain"] and E["kinetic"] > 0
    assert set(E) >= {"kinetic", "strain", "external_work", "reaction_work", "initial", "balance_error", "friction", "impact"}
    sim.advance_to(1.0)  # beyond t_end: stops there
    assert sim.finished and sim.t == pytest.approx(2e-5, rel=1e-12)
    with pytest.raises(RuntimeError, match="finished"):
        sim.step()


def test_write_frame_and_context_manager(tmp_path):
    out = tmp_path / "frames.h5"
    with otmpm.Simulation(short_dyka(**{"output.every": 0.0}), out=str(out)) as sim:
        sim.advance_to(1e-5)
        sim.write_frame()
        t_frame = sim.t
        sim.advance_to(sim.t_end)
    with otmpm.results.open(out) as r:  # frames at 0, t_frame and t_end; status set by __exit__
        assert r.status == "ok" and len(r.frames) == 3 and r.frames[1].time == t_frame


def test_context_manager_marks_an_abandoned_run_interrupted(tmp_path):
    out = tmp_path / "abandoned.h5"
    with pytest.raises(KeyError):
        with otmpm.Simulation(short_dyka(), out=str(out)) as sim:
            sim.step(3)
            raise KeyError("stop")
    with otmpm.results.open(out) as r:
        assert r.status == "interrupted" and r.attrs["steps"] == 3
    with pytest.raises(RuntimeError, match="already called"):
        sim.finish()


def test_three_dimensional_views():
    sim = otmpm.Simulation(otmpm.Scene.from_toml(example("dyka_3d.toml"), {"simulation.t_end": 1e-6}),
                           write_results=False)
    sim.step()
    n = len(sim.particles)
    assert sim.particles.x.shape == (n, 3) and sim.particles.x.strides == (24, 8)
    assert sim.particles.stress.shape == (n, 3, 3) and sim.particles.stress.strides == (72, 8, 24)
    assert np.array_equal(sim.particles.stress, np.transpose(sim.particles.stress, (0, 2, 1)))  # symmetric
    assert sim.nodes.x.shape == (len(sim.nodes), 3)
    assert sim.particles.stress_zz is None  # 3D: sigma_zz is stress[:, 2, 2]


def test_a_simulation_stepped_in_another_thread_refuses_other_calls():
    import threading
    import time
    sim = otmpm.Simulation(otmpm.Scene.from_toml(example("dyka/dyka_n1333.toml"), {"simulation.t_end": 4e-6}),
                           write_results=False)
    worker = threading.Thread(target=sim.advance_to, args=(sim.t_end,))
    worker.start()
    refused = 0
    while worker.is_alive():
        try:
            sim.step()
        except RuntimeError as e:
            refused += "another thread is stepping" in str(e)
        time.sleep(0.002)
    worker.join()
    assert refused > 0 and sim.finished  # the other thread stepped alone to t_end


def j2_strip(**overrides):
    """A 2D plane-strain steel strip whose left quarter hits the fixed right
    end at 5 m/s: the impact stress (about 100 MPa) exceeds the j2 yield
    stress (50 MPa), so the material yields (tests/test_plastic_runs.cpp)."""
    d = {
        "simulation": {"dimension": 2, "mode": "mpm", "integrator": "musl", "t_end": 2e-5, "cfl": 0.1},
        "basis": {"kind": "linear"},
        "grid": {"lower": [-0.01, 0.0], "upper": [0.1, 0.005], "cells": [22, 1]},
        "material": [{"name": "m", "model": "j2", "density": 7833.0, "young": 200e9, "poisson": 0.3,
                      "yield_stress": 5e7, "hardening_modulus": 1e9}],
        "body": [{"name": "bar", "material": "m", "lower": [0.0, 0.0], "upper": [0.1, 0.005]}],
        "initial_velocity": [{"lower": [0.0, 0.0], "upper": [0.025, 0.005], "velocity": [-5.0, 0.0]}],
        "boundary": [
            {"name": "end", "lower": [0.1, 0.0], "upper": [0.1, 0.005], "fix": [True, False]},
            {"name": "bottom", "lower": [-0.01, 0.0], "upper": [0.1, 0.0], "fix": [False, True]},
            {"name": "top", "lower": [-0.01, 0.005], "upper": [0.1, 0.005], "fix": [False, True]},
        ],
        "output": {"fields": ["x", "v", "plastic_strain"], "every": 1e-5},
    }
    return otmpm.Scene.from_dict(d, overrides)


HENCKY_STATE = {"elastic_left_cauchy_green": 6, "plastic_strain": 1, "volumetric_plastic_strain": 1,
                "elastic_energy": 1, "plastic_work": 1}


def test_j2_state_arrays_are_views_that_follow_the_steps(tmp_path):
    out = tmp_path / "j2.h5"
    with otmpm.Simulation(j2_strip(), out=str(out)) as sim:
        state = sim.particles.state
        n = len(sim.particles)
        assert {k: (v.shape[1] if v.ndim == 2 else 1) for k, v in state.items()} == HENCKY_STATE
        assert all(v.shape[0] == n and not v.flags.writeable for v in state.values())
        eps_p = state["plastic_strain"]
        assert not eps_p.any()  # no plastic flow before the first step
        np.testing.assert_array_equal(state["elastic_left_cauchy_green"], np.tile([1, 1, 1, 0, 0, 0], (n, 1)))
        sim.advance_to(sim.t_end)
        # The view taken before the run shows the state at t_end: the engine's memory.
        assert np.shares_memory(eps_p, sim.particles.state["plastic_strain"])
        assert eps_p.max() > 1e-4 and eps_p.min() >= 0.0  # the impact yielded the struck end, nothing unloads to < 0
        # The energy balance sums the same arrays: dissipated = sum of the
        # particles' plastic work, strain = sum of their elastic energy
        # (summed in chunks: equal to rounding).
        E = sim.energy()
        assert E["dissipated"] > 0.05 * E["initial"]
        assert np.isclose(state["plastic_work"].sum(), E["dissipated"], rtol=1e-12, atol=0)
        assert np.isclose(state["elastic_energy"].sum(), E["strain"], rtol=1e-12, atol=0)
        final = eps_p.copy()
    # The result file's plastic_strain field at t_end is the same array, bit for bit.
    np.testing.assert_array_equal(final_frame(out)["plastic_strain"].reshape(-1), final)


def test_interrupt_ends_the_run_with_status_interrupted(tmp_path):
    out = tmp_path / "stopped.h5"
    sim = otmpm.Simulation(short_dyka(), out=str(out))
    sim.step(4)
    sim.interrupt()
    assert sim.finished and sim.status == "interrupted"
    with pytest.raises(RuntimeError, match="finished"):
        sim.interrupt()
    s = sim.finish()
    assert s.interrupted and s.exit_code == 130 and s.steps == 4 and str(s).startswith("INTERRUPTED: ")
    assert s.errors == {} or "rms_velocity_error" not in s.errors  # no final errors for a run cut short
    with otmpm.results.open(out) as r:
        assert r.status == "interrupted" and r.attrs["steps"] == 4
    done = otmpm.run(short_dyka(), write_results=False)
    assert not done.interrupted and done.exit_code == 0


def test_stress_zz_of_linear_elastic_plane_strain_is_nu_times_the_in_plane_trace():
    """linear_elastic in plane strain (eps_zz = 0): sigma_zz = lambda tr(eps) =
    nu (sigma_xx + sigma_yy), to round-off; stress_zz is a new array each time
    (derived from the strain), not a view that follows the steps."""
    nu = 0.3
    scene = otmpm.Scene.from_toml(example("dyka_2d.toml"), {"material.steel.poisson": nu, "simulation.t_end": 2e-5})
    sim = otmpm.Simulation(scene, write_results=False)
    p = sim.particles
    assert p.stress_zz.shape == (len(p),) and not p.stress_zz.any()  # unstrained before the first step
    sim.advance_to(1e-5)
    zz, s = p.stress_zz, p.stress
    assert zz.dtype == np.float64 and zz.flags.owndata and not zz.flags.writeable
    scale = np.abs(s).max()
    assert np.abs(zz).max() > 0.1 * scale  # the impact loads it
    np.testing.assert_allclose(zz, nu * (s[:, 0, 0] + s[:, 1, 1]), rtol=0, atol=1e-12 * scale)
    before = zz.copy()
    sim.step(5)
    assert np.array_equal(zz, before) and not np.array_equal(p.stress_zz, before)


def test_stress_zz_is_what_the_result_file_holds(tmp_path):
    """j2 (sigma_zz from the elastic b_e of the Hencky law): the values at
    t_end are the final frame's stress_zz (output.fields), bit for bit."""
    out = tmp_path / "zz.h5"
    with otmpm.Simulation(j2_strip(**{"output.fields": ["x", "stress", "stress_zz"]}), out=str(out)) as sim:
        sim.advance_to(sim.t_end)
        zz = sim.particles.stress_zz
        assert sim.particles.state["plastic_strain"].max() > 1e-4  # yielded: not the elastic nu (sxx + syy)
    with otmpm.results.open(out) as r:
        last = r.frames[-1]
        assert last.time == sim.t
        np.testing.assert_array_equal(last["stress_zz"], zz)
    assert np.abs(zz).max() > 1e6
