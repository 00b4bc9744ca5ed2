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


def test_symmetric_and_single_layouts_read_as_the_full_tensor(tmp_path):
    """output.symmetric_tensors / output.precision: the reader gives the same
    (particles, D, D) stress and strain as from the default layout (float32
    values: the doubles rounded), in 3D (6 components) and 2D (3)."""
    cases = {3: (example("dyka_3d.toml"), ["simulation.t_end=4e-6", "output.every=2e-6"]),
             2: (example("mms_plate.toml"), ["grid.cells=[8, 8]", "simulation.t_end=5e-4"])}
    for dim, (scene, sets) in cases.items():
        sets = sets + ['output.fields=["x", "v", "stress", "strain", "F"]']
        files = {}
        for name, extra in {"full": [], "sym": ["output.symmetric_tensors=true"],
                            "single": ["output.symmetric_tensors=true", "output.precision=single"]}.items():
            out = tmp_path / f"{name}_{dim}d.h5"
            args = ["run", scene, "--out", out, "--quiet"]
            for s in sets + extra:
                args += ["--set", s]
            done = run_cli(*args)
            assert done.returncode == 0, done.stderr
            files[name] = out
        with otmpm.results.open(files["full"]) as full, otmpm.results.open(files["sym"]) as sym, \
                otmpm.results.open(files["single"]) as single:
            for field in ("stress", "strain"):
                a, b, c = full.field(field), sym.field(field), single.field(field)
                assert a.shape[-2:] == (dim, dim) and b.shape == a.shape and c.shape == a.shape
                assert np.any(a != 0)  # a loaded body: not a comparison of zeros
                assert b.dtype == np.float64 and np.array_equal(a, b)
                assert c.dtype == np.float32 and np.array_equal(c, a.astype(np.float32))
                stored = sym.frames[-1]._group[field]
                assert stored.shape[1] == dim * (dim + 1) // 2
                assert otmpm.results.unpack_symmetric(stored[()], stored.attrs["components"], dim).shape[1] == dim * dim
            assert np.array_equal(full.field("F"), sym.field("F"))  # not symmetric: stored whole
            assert np.array_equal(full.probes["A"]["stress"] if "A" in full.probes else 0,
                                  sym.probes["A"]["stress"] if "A" in sym.probes else 0)
