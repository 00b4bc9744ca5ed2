"""otmpm.Scene and otmpm.InputError: the scene reader of the command line
from Python, with the same messages, lines and keys."""
import glob
import math
import os

import pytest

import otmpm
from conftest import SOURCE, example, run_cli

DYKA = example("dyka/dyka_n40.toml")
BAD = sorted(glob.glob(str(SOURCE / "tests" / "scenes" / "bad" / "*.toml")))


def cli_error(*args):
    """The message `otmpm run ARGS` prints for bad input (exit status 2)."""
    done = run_cli("run", *args, "--out", os.devnull + ".h5", "--quiet")
    assert done.returncode == 2, done.stderr
    line = done.stderr.strip().splitlines()[-1]
    assert line.startswith("otmpm: error: ")
    return line[len("otmpm: error: "):]


def python_error(path, overrides=None):
    """The InputError of reading and assembling the scene from Python."""
    with pytest.raises(otmpm.InputError) as info:
        otmpm.run(otmpm.Scene.from_toml(path, overrides), write_results=False)
    return info.value


def test_from_toml_reads_the_file_and_overrides():
    scene = otmpm.Scene.from_toml(DYKA, overrides={"material.steel.young": 70e9, "simulation.integrator": "fe"})
    d = scene.to_dict()
    assert d["material"][0]["young"] == 70e9
    assert d["simulation"]["integrator"] == "fe"
    assert (scene.dimension, scene.mode, scene.integrator, scene.basis) == (1, "mpm", "fe", "lme")
    assert scene.file == DYKA and scene.t_end == 1e-4 and scene.output_file == "dyka_n40.h5"


def test_overrides_as_a_dict_equal_the_command_line_strings():
    as_dict = otmpm.Scene.from_toml(DYKA, {"basis.gamma_lme": 2, "grid.cells": [45], "output.every": 2e-6})
    as_set = otmpm.Scene.from_toml(DYKA, ["basis.gamma_lme=2", "grid.cells=[45]", "output.every=2e-6"])
    assert as_dict.to_toml() == as_set.to_toml()


def test_to_dict_from_dict_round_trip_is_exact():
    scene = otmpm.Scene.from_toml(DYKA, {"grid.lower": [-0.1 / 3]})
    again = otmpm.Scene.from_dict(scene.to_dict())
    assert again.to_dict() == scene.to_dict()
    assert again.to_toml() == scene.to_toml()  # also the text, for scenes written in the files' style
    assert again.to_dict()["grid"]["lower"][0] == -0.1 / 3  # floats survive the text bit for bit


def test_from_dict_accepts_numpy_values():
    import numpy as np
    d = otmpm.Scene.from_toml(DYKA).to_dict()
    d["grid"]["lower"] = np.array([-0.006665])
    d["grid"]["cells"] = [np.int64(42)]
    d["simulation"]["cfl"] = np.float32(0.25)
    scene = otmpm.Scene.from_dict(d)
    assert scene.to_dict()["grid"]["cells"] == [42]
    assert scene.to_dict()["simulation"]["cfl"] == float(np.float32(0.25))


@pytest.mark.parametrize("path", BAD, ids=os.path.basename)
def test_bad_scenes_raise_the_command_lines_message(path):
    e = python_error(path)
    assert str(e) == cli_error(path)
    assert e.file == path and e.line is not None and e.line >= 1 and not e.override


def test_input_error_carries_line_and_key():
    e = python_error(str(SOURCE / "tests/scenes/bad/unknown_key.toml"))
    assert (e.line, e.key) == (22, "material.steel.yuong")
    e = python_error(str(SOURCE / "tests/scenes/bad/syntax.toml"))
    assert e.line == 21 and e.key is None


def test_bad_override_raises_the_command_lines_message():
    e = python_error(DYKA, ["material.steel.yung=1"])
    assert str(e) == cli_error(DYKA, "--set", "material.steel.yung=1")
    assert e.override and e.key == "material.steel.yung" and e.file is None and e.line is None
    e = python_error(DYKA, {"simulation.t_end": "soon"})
    assert str(e) == "--set simulation.t_end: expected a number, got a string"


def test_from_dict_errors_name_the_key():
    d = otmpm.Scene.from_toml(DYKA).to_dict()
    d["material"][0]["density"] = -1.0
    with pytest.raises(otmpm.InputError) as info:
        otmpm.Scene.from_dict(d)
    assert info.value.file == "<dict>" and info.value.key == "material.steel.density"
    assert str(info.value).endswith("key 'material.steel.density': must be > 0 (got -1)")
    with pytest.raises(otmpm.InputError, match="key 'simulation.t_end': a set cannot be a scene value"):
        otmpm.Scene.from_dict({"simulation": {"t_end": {1}}})
    with pytest.raises(otmpm.InputError, match="integer 1267650600228229401496703205376 out of range"):
        otmpm.Scene.from_dict({"simulation": {"dimension": 2**100}})


def test_missing_file():
    with pytest.raises(otmpm.InputError, match="no_such.toml: cannot open the scene file") as info:
        otmpm.Scene.from_toml("no_such.toml")
    assert info.value.file == "no_such.toml"


def test_with_overrides_returns_a_changed_copy():
    scene = otmpm.Scene.from_toml(DYKA)
    ul = scene.with_overrides({"simulation.mode": "ul"})
    assert (scene.mode, ul.mode) == ("mpm", "ul")
    assert math.isclose(ul.t_end, scene.t_end)
