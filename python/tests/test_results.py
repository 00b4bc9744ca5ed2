"""otmpm.results.open on files written by the command line and by otmpm.run."""
import numpy as np

import otmpm
from conftest import example, run_cli

DYKA = example("dyka/dyka_n40.toml")


def test_reads_a_file_written_by_the_command_line(tmp_path):
    out = tmp_path / "cli.h5"
    done = run_cli("run", DYKA, "--out", out, "--quiet", "--set", "output.fields=[\"x\",\"v\",\"stress\",\"F\",\"volume\"]")
    assert done.returncode == 0, done.stderr
    with otmpm.results.open(out) as r:
        assert r.status == "ok" and r.dimension == 1 and r.attrs["steps"] > 0
        assert r.scene["basis"]["kind"] == "lme" and r.scene["material"][0]["name"] == "steel"
        assert otmpm.Scene.from_dict(r.scene).to_toml() == r.scene_text  # the scene as it was run
        assert set(r.errors) == {"rms_velocity_error", "rms_displacement_error", "rms_stress_error", "history_error_A"}
        assert len(r.frames) == 101 and r.times[0] == 0.0 and r.times[-1] == r.attrs["t_end"]
        last = r.frames[-1]
        assert set(last) >= {"x", "v", "stress", "F", "volume"}
        assert last["x"].shape == (80, 1) and last["stress"].shape == (80, 1, 1) and last["volume"].shape == (80,)
        v = r.field("v")
        assert v.shape == (101, 80, 1) and np.array_equal(v[-1], last["v"])
        A = r.probes["A"]
        assert A["time"].shape == (101,) and A["x"].shape == (101, 1) and A["stress"].shape == (101, 1, 1)
        assert np.array_equal(A["time"], r.times)
        assert A["v"][0, 0] == -5.0  # point A starts with the impact velocity
        E = r.energy
        assert set(E) == {"time", "kinetic", "strain", "external_work", "reaction_work"}
        assert E["kinetic"][0] > 0 and len(E["time"]) == 101


def test_reads_what_otmpm_run_wrote(tmp_path):
    out = tmp_path / "py.h5"
    s = otmpm.run(otmpm.Scene.from_toml(DYKA, {"simulation.t_end": 1e-5}), out=str(out))
    with otmpm.results.open(out) as r:
        assert r.attrs["steps"] == s.steps and r.errors == s.errors
        assert r.attrs["max_energy_ratio"] == s.max_energy_ratio
