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
                # 2D stress: and plane strain's sigma_zz ("xx xy yy zz"), read as frame["stress_zz"]
                assert stored.shape[1] == dim * (dim + 1) // 2 + (dim == 2 and field == "stress")
                assert otmpm.results.unpack_symmetric(stored[()], stored.attrs["components"], dim).shape[1] == dim * dim
            assert np.array_equal(full.field("F"), sym.field("F"))  # not symmetric: stored whole
            assert np.array_equal(full.probes["A"]["stress"] if "A" in full.probes else 0,
                                  sym.probes["A"]["stress"] if "A" in sym.probes else 0)


def test_plane_strain_stress_zz_from_either_layout_and_old_files(tmp_path):
    """2D: frame["stress_zz"] is sigma_zz from the symmetric stress's "zz"
    column or from the field stress_zz (the same bits); frame["stress"] stays
    (particles, 2, 2) in every layout; a file of the old 3-component layout
    still reads (no stress_zz). The values meet the plane-strain relation of
    the Hencky models, tr(tau) = 3/2 K ln det b_e, with the stored in-plane
    stress, b_e and F (column collapse, drucker_prager, yielding)."""
    import h5py
    import shutil

    scene = example("column_collapse.toml")
    fields = '["x", "stress", "F", "elastic_left_cauchy_green", "plastic_strain", "stress_zz"]'
    sets = ["simulation.t_end=0.05", "output.every=0.025", f"output.fields={fields}"]
    files = {}
    for name, extra in {"full": [], "sym": ["output.symmetric_tensors=true"]}.items():
        out = tmp_path / f"{name}.h5"
        args = ["run", scene, "--out", out, "--quiet"]
        for s in sets + extra:
            args += ["--set", s]
        done = run_cli(*args)
        assert done.returncode == 0, done.stderr
        files[name] = out
    old = tmp_path / "old.h5"  # the layout of otmpm before sigma_zz: stress "xx xy yy", no stress_zz
    shutil.copy(files["sym"], old)
    with h5py.File(old, "r+") as f:
        for g in f["frames"].values():
            three = g["stress"][:, :3]
            del g["stress"], g["stress_zz"]
            g["stress"] = three
            g["stress"].attrs["components"] = "xx xy yy"
    with otmpm.results.open(files["full"]) as full, otmpm.results.open(files["sym"]) as sym, \
            otmpm.results.open(old) as before:
        young, nu = full.scene["material"][0]["young"], full.scene["material"][0]["poisson"]
        K = young / (3 * (1 - 2 * nu))
        for a, b, c in zip(full.frames, sym.frames, before.frames):
            assert "stress_zz" in a and "stress_zz" in b and "stress_zz" not in c
            assert b._group["stress"].shape[1] == 4 and otmpm.results._value(b._group["stress"].attrs["components"]) == "xx xy yy zz"
            assert np.array_equal(b["stress_zz"], b._group["stress"][:, 3])
            assert np.array_equal(a["stress_zz"], b["stress_zz"]) and a["stress_zz"].shape == (len(a["x"]),)
            assert a["stress"].shape == b["stress"].shape == c["stress"].shape == (len(a["x"]), 2, 2)
            assert np.array_equal(a["stress"], b["stress"]) and np.array_equal(a["stress"], c["stress"])
            with np.testing.assert_raises(KeyError):
                c["stress_zz"]
            s, F, be = b["stress"], b["F"], b["elastic_left_cauchy_green"]  # b_e: xx yy zz xy yz xz
            J = F[:, 0, 0] * F[:, 1, 1] - F[:, 0, 1] * F[:, 1, 0]
            det_b = (be[:, 0] * be[:, 1] - be[:, 3] ** 2) * be[:, 2]
            zz = 1.5 * K * np.log(det_b) / J - s[:, 0, 0] - s[:, 1, 1]
            assert np.max(np.abs(b["stress_zz"] - zz)) <= 1e-13 * K
        assert np.max(np.abs(sym.frames[-1]["stress_zz"])) > 1e3  # gravity loads the column
        assert np.max(sym.frames[-1]["plastic_strain"]) > 0  # and it yields
        assert sym.field("stress_zz").shape == (len(sym.frames), len(sym.frames[0]["x"]))


def test_restart_of_a_file_with_the_old_2d_layout_keeps_it(tmp_path):
    """A restart continues a result file whose symmetric 2D stress has the 3
    columns of otmpm before sigma_zz ("xx xy yy") with 3 columns: the file
    stays what the interrupted run would have written (the in-plane values
    are the same bits as a run of this otmpm); one of this otmpm goes on with 4."""
    import h5py

    sets = ["grid.cells=[8, 8]", "output.every=2.5e-4", "output.checkpoint_every=10", "output.symmetric_tensors=true"]
    args = ["run", example("mms_plate.toml"), "--quiet", "--out", tmp_path / "plate.h5"]
    for s in sets:
        args += ["--set", s]
    done = run_cli(*args)
    assert done.returncode == 0, done.stderr
    checkpoint = tmp_path / "plate.checkpoint.h5"
    with h5py.File(checkpoint, "r") as c:
        copied = int(c["recorder"].attrs["frames"]) if "frames" in c["recorder"].attrs else None
    now = run_cli("run", "--restart", checkpoint, "--out", tmp_path / "now.h5", "--quiet")
    assert now.returncode == 0, now.stderr
    with h5py.File(tmp_path / "plate.h5", "r+") as f:  # the old layout
        for g in f["frames"].values():
            three = g["stress"][:, :3]
            del g["stress"]
            g["stress"] = three
            g["stress"].attrs["components"] = "xx xy yy"
    old = run_cli("run", "--restart", checkpoint, "--out", tmp_path / "old.h5", "--quiet")
    assert old.returncode == 0, old.stderr
    with h5py.File(tmp_path / "old.h5", "r") as a, h5py.File(tmp_path / "now.h5", "r") as b:
        names = sorted(a["frames"])
        assert names == sorted(b["frames"]) and len(names) > 2
        for name in names:
            sa, sb = a["frames"][name]["stress"], b["frames"][name]["stress"]
            assert otmpm.results._value(sa.attrs["components"]) == "xx xy yy"
            assert otmpm.results._value(sb.attrs["components"]) == "xx xy yy zz"
            assert np.array_equal(sa[()], sb[()][:, :3])
    assert copied is None or 0 < copied < len(names)
