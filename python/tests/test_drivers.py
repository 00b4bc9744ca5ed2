"""otmpm.pair (through the library) and otmpm.study (through the otmpm command)."""
import h5py
import pytest

import otmpm
from conftest import example, run_cli

DYKA = example("dyka/dyka_n40.toml")


def attrs(path):
    with h5py.File(path, "r") as f:
        return dict(f.attrs)


def test_pair_equals_the_command_line(tmp_path):
    scene = otmpm.Scene.from_toml(DYKA, {"output.file": str(tmp_path / "py.h5")})
    runs = otmpm.pair(scene)
    assert list(runs) == ["mpm", "ul"] and runs["ul"].mode == "ul" and runs["mpm"].mode == "mpm"
    done = run_cli("pair", DYKA, "--set", f"output.file={tmp_path / 'cli.h5'}", "--quiet")
    assert done.returncode == 0, done.stderr
    for mode, s in runs.items():
        assert s.out_file == str(tmp_path / f"py_{mode}.h5")
        cli = attrs(tmp_path / f"cli_{mode}.h5")
        assert s.steps == cli["steps"]
        for name, value in s.errors.items():
            assert value == cli[name], (mode, name)


def test_study_runs_the_command_and_returns_the_rows(tmp_path):
    study = tmp_path / "tiny.toml"
    study.write_text(f"""
scene = "{example('dyka.toml')}"
jobs = 2
set = ["simulation.t_end=1e-5", "output.every=0"]
[sweep]
"simulation.integrator" = ["fe", "npc"]
[[mesh]]
name = "n13"
h = 0.010253846153846153
set = ["grid.cells=[15]", "grid.lower=[-0.020507692307692307]"]
""")
    result = otmpm.study(study)
    assert result.csv == str(tmp_path / "tiny.csv")
    assert len(result.rows) == 2 and {r["simulation.integrator"] for r in result.rows} == {"fe", "npc"}
    assert all(r["status"] == "ok" and r["exit_code"] == 0 and r["rms_velocity_error"] > 0 for r in result.rows)
    again = otmpm.study(study)  # resumes: nothing to run, the same rows
    assert again.rows == result.rows


def test_study_bad_input(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('scene = "no_such_scene.toml"\n[[mesh]]\nname = "a"\nh = 1.0\nset = []\n')
    with pytest.raises(otmpm.InputError, match="no such file"):
        otmpm.study(bad)
