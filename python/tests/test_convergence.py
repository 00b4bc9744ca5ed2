"""otmpm.convergence: errors against a reference run, observed orders and
Richardson estimates (the study's [[measure]] tables and Python functions)."""
import csv
import math

import numpy as np
import pytest

import otmpm
from otmpm import convergence
from conftest import example, run_cli


def test_observed_order_and_richardson_recover_a_power_law():
    h = [0.4, 0.25, 0.1]  # uneven ratios
    e = [3.0 * x**2 for x in h]
    assert convergence.observed_order(h, e)[1:] == pytest.approx([2.0, 2.0], rel=1e-12)
    assert math.isnan(convergence.observed_order(h, e)[0])
    q = [1.5 + 0.7 * x**1.5 for x in h]  # converges to 1.5 at order 1.5
    limit, p = convergence.richardson(h, q)
    assert p == pytest.approx(1.5, rel=1e-9)
    assert limit == pytest.approx(1.5, rel=1e-9)
    assert all(math.isnan(v) for v in convergence.richardson(h, [1.0, 2.0, 1.5]))  # not monotone


def test_error_of_scalars_arrays_and_series():
    assert convergence.error(2.5, 2.0) == 0.5  # absolute, in the measure's units
    assert convergence.error(np.array([3.0, 4.0]), np.array([0.0, 0.0]) + [3.0, 0.0]) == pytest.approx(4 / 3)
    t_ref, t = np.linspace(0, 1, 11), np.linspace(0, 1, 101)
    series = (t, 2 * t)  # interpolated to the reference's times: exact for a line
    assert convergence.error(series, (t_ref, 2 * t_ref)) == pytest.approx(0.0, abs=1e-15)
    assert convergence.error((t, 2.2 * t), (t_ref, 2 * t_ref)) == pytest.approx(0.1, rel=1e-12)


STUDY = """
scene = "{scene}"
jobs = 2
set = ["simulation.t_end=6e-5", "output.every=2e-5", "simulation.integrator=npc", "basis.kind=linear"]
[[mesh]]
name = "n13"
h = 0.010253846153846153
set = ["grid.cells=[15]", "grid.lower=[-0.020507692307692307]"]
[[mesh]]
name = "n20"
h = 0.006665
set = ["grid.cells=[22]", "grid.lower=[-0.01333]"]
[[mesh]]
name = "n40"
h = 0.0033325
set = ["grid.cells=[42]", "grid.lower=[-0.006665]"]
[[mesh]]
name = "n133"
h = 0.0010022556390977444
set = ["grid.cells=[135]", "grid.lower=[-0.002004511278195489]"]
[[measure]]
name = "length"
kind = "extent"
axis = 0
initial = 0.1333
[[measure]]
name = "velocity"
kind = "field"
field = "v"
points = [[0.01], [0.05], [0.09], [0.12]]
[[measure]]
name = "kinetic"
kind = "energy"
series = "kinetic"
"""


def test_a_study_measures_every_run_against_its_finest(tmp_path):
    study = tmp_path / "dyka_ref.toml"
    study.write_text(STUDY.format(scene=example("dyka.toml")))
    otmpm.study(study)  # runs, then writes dyka_ref_errors.csv and the plots
    with open(tmp_path / "dyka_ref_errors.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["mesh"] for r in rows] == ["n13", "n20", "n40", "n133"]  # coarse to fine
    for name in ("length", "velocity", "kinetic"):
        assert float(rows[-1][name + "_error"]) == 0.0  # the reference itself
        errors = [float(r[name + "_error"]) for r in rows[:-1]]
        assert all(e > 0 for e in errors)
        assert (tmp_path / f"dyka_ref_errors_{name}_convergence.png").stat().st_size > 0
    # the velocity field converges: its error drops from the coarsest to the finest but one
    velocity = [float(r["velocity_error"]) for r in rows[:-1]]
    assert velocity[-1] < velocity[0]
    # the observed order is log(e_i-1 / e_i) / log(h_i-1 / h_i), as printed
    e, h = [float(r["kinetic_error"]) for r in rows[:2]], [float(r["h"]) for r in rows[:2]]
    assert float(rows[1]["kinetic_order"]) == pytest.approx(math.log(e[0] / e[1]) / math.log(h[0] / h[1]), rel=1e-6)
    # a Python function of the result is a measure too: the same extent by hand
    table = convergence.reference_errors(study, functions={
        "by_hand": lambda r: float(np.ptp(r.frames[-1]["x"][:, 0])) + 0.1333 - float(np.ptp(r.frames[0]["x"][:, 0]))},
        out=False)
    for row in table:
        assert row["by_hand_error"] == pytest.approx(row["length_error"], abs=1e-15)  # m: round-off of 0.13 m


def test_a_bad_measure_stops_the_study_before_any_run(tmp_path):
    study = tmp_path / "bad.toml"
    study.write_text(STUDY.format(scene=example("dyka.toml")).replace('kind = "energy"', 'kind = "energie"'))
    r = run_cli("study", study)
    assert r.returncode == 2
    assert "bad.toml:33: key 'measure.kinetic.kind': must be one of" in r.stderr
    assert not (tmp_path / "bad_results").exists()  # nothing ran
