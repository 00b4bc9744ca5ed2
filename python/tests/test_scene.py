"""otmpm.Scene and otmpm.InputError: the scene reader of the command line
from Python, with the same messages, lines and keys."""
import glob
import math
import os
import tomllib

import numpy as np
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


# A 2D scene with what the scene format gained with plasticity, shapes and
# walls: a j2 material with a [material.johnson_cook] table, an
# explicit_alpha integrator with its rho_inf, bodies of every 2D shape (box,
# sphere, polygon, a particle file) and a moving rigid wall with friction.
NEW_CONTENT = """
[simulation]
dimension = 2
integrator = "explicit_alpha"
rho_inf = 0.5
t_end = 1e-4
cfl = 0.2
[basis]
kind = "linear"
[grid]
lower = [-1.0, -1.0]
upper = [1.0, 1.0]
cells = [20, 20]
[[material]]
name = "m"
model = "j2"
density = 2000.0
young = 1e7
poisson = 0.3
yield_stress = 1e5
hardening_modulus = 1e5
[material.johnson_cook]
B = 1e5
n = 0.5
C = 0.01
reference_strain_rate = 1.0
[[body]]
name = "plate"
material = "m"
lower = [-0.5, -0.8]
upper = [0.5, -0.5]
[[body]]
name = "ball"
material = "m"
shape = "sphere"
center = [0.0, -0.2]
radius = 0.25
velocity = [0.0, -1.0]
[[body]]
name = "wedge"
material = "m"
shape = "polygon"
vertices = [[0.3, 0.2], [0.8, 0.2], [0.3, 0.7]]
[[body]]
name = "cloud"
material = "m"
shape = "file"
file = "cloud.csv"
[[wall]]
name = "floor"
point = [0.0, -0.8]
normal = [0.0, 1.0]
friction = 0.2
[[wall]]
name = "piston"
point = [-0.9, 0.0]
normal = [1.0, 0.0]
velocity = [0.5, 0.0]
[body_force]
value = [0.0, -9.81]
"""

CLOUD = "x, y, volume, vx, vy\n-0.6, 0.45, 0.0025, 0.0, 0.0\n-0.5, 0.45, 0.0025, 1.0, 0.0\n-0.4, 0.45, 0.0025, 0.0, -1.0\n"


def positions_after_steps(scene, n=20):
    with otmpm.Simulation(scene, write_results=False) as sim:
        sim.step(n)
        return sim.particles.x.copy()


def test_new_scene_content_round_trips_through_to_dict_and_to_toml(tmp_path, monkeypatch):
    folder = tmp_path / "scenes"
    folder.mkdir()
    (folder / "cloud.csv").write_text(CLOUD)
    (folder / "impact.toml").write_text(NEW_CONTENT)
    scene = otmpm.Scene.from_toml(folder / "impact.toml")
    monkeypatch.chdir(tmp_path)  # the particle file is not where a dict's relative path would point
    d = scene.to_dict()
    assert d["simulation"]["rho_inf"] == 0.5 and d["material"][0]["johnson_cook"]["n"] == 0.5
    assert [b.get("shape", "box") for b in d["body"]] == ["box", "sphere", "polygon", "file"]
    assert d["body"][3]["file"] == str(folder / "cloud.csv")  # absolute: reads back from anywhere
    assert [w["name"] for w in d["wall"]] == ["floor", "piston"] and d["wall"][1]["velocity"] == [0.5, 0.0]
    full = scene.to_dict(full=True)  # every value, defaults included
    assert full["simulation"]["rho_inf"] == 0.5 and full["wall"][0]["velocity"] == [0.0, 0.0]
    assert full["body"][0]["shape"] == "box" and full["body"][1]["radius"] == 0.25
    assert full["body"][3]["file"] == str(folder / "cloud.csv")
    for as_full in (False, True):
        again = otmpm.Scene.from_dict(scene.to_dict(full=as_full))
        assert again.to_dict(full=as_full) == scene.to_dict(full=as_full)
        assert again.to_toml(full=True) == scene.to_toml(full=True)
        assert tomllib.loads(scene.to_toml(full=as_full)) == scene.to_dict(full=as_full)
    # Read back, the scene runs to the same bits (the walls, shapes and rho_inf took part).
    x = positions_after_steps(scene)
    assert len(x) > 100
    for as_full in (False, True):
        np.testing.assert_array_equal(positions_after_steps(otmpm.Scene.from_dict(scene.to_dict(full=as_full))), x)
    without_walls = {k: v for k, v in d.items() if k != "wall"}
    assert not np.array_equal(positions_after_steps(otmpm.Scene.from_dict(without_walls)), x)


@pytest.mark.parametrize("name", ["dyka/dyka_n40.toml", "dyka_2d.toml", "dyka_3d.toml", "fixed_bar.toml",
                                  "traction_bar.toml", "mms_plate.toml", "andersen_block.toml", "plate_impact.toml"])
def test_full_dict_of_every_example_reads_back_to_the_same_scene(name):
    scene = otmpm.Scene.from_toml(example(name))
    full = otmpm.Scene.from_dict(scene.to_dict(full=True), name=name)
    assert full.to_toml(full=True) == scene.to_toml(full=True)
    assert set(scene.to_dict()) <= set(scene.to_dict(full=True))  # full adds defaults, drops nothing
