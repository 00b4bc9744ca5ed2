"""The Python package under hostile use (docs/stability.md, "What the Python
package guarantees"): every method of a finished Simulation, one dropped or
left at exit unfinished, scene dicts that contain themselves or nest without
end, override values with line breaks or NUL, result files of other programs
and FIFOs given to otmpm.results.open, basis grids beyond the node cap or with
values that are not what they seem, and the read-only Summary."""
import gc
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

import otmpm
import otmpm.basis
import otmpm.results
from conftest import example

DYKA = example("dyka.toml")
SHORT = {"simulation.t_end": 2e-5, "output.every": 5e-6}


def short_dyka(**extra):
    return otmpm.Scene.from_toml(DYKA, {**SHORT, **extra})


def status_of(path):
    with h5py.File(path, "r") as f:
        return f.attrs["status"].decode() if isinstance(f.attrs["status"], bytes) else f.attrs["status"]


def lock_files(directory):
    return sorted(n for n in os.listdir(directory) if n.endswith(".otmpm-lock"))


# ---------------------------------------------------------------- a finished Simulation


@pytest.mark.parametrize("how", ["finish", "with"])
def test_every_method_that_changes_a_finished_run_raises_runtime_error(tmp_path, how):
    out = str(tmp_path / "r.h5")
    if how == "with":
        with otmpm.Simulation(short_dyka(), out=out) as sim:
            sim.step(5)
    else:
        sim = otmpm.Simulation(short_dyka(), out=out)
        sim.step(5)
        sim.finish()
    with h5py.File(out, "r") as f:
        frames = len(f["frames"])
    for call in (sim.write_frame, sim.interrupt, sim.finish, sim.step, lambda: sim.advance_to(1.0)):
        with pytest.raises(RuntimeError, match="finish"):
            call()
    with h5py.File(out, "r") as f:
        assert len(f["frames"]) == frames
    assert status_of(out) == "ok"
    # What reads the state stays valid: properties, energy() and the views.
    assert sim.finished and sim.steps == 5 and sim.status == "ok"
    assert sim.particles.x.shape == (80, 1) and sim.energy()["kinetic"] > 0 and len(sim.nodes) == 43


# ---------------------------------------------------------------- locks and unfinished runs


def test_finish_releases_the_locks_while_the_object_lives(tmp_path):
    out = str(tmp_path / "r.h5")
    sim = otmpm.Simulation(short_dyka(), out=out)
    sim.advance_to(sim.t_end)
    assert lock_files(tmp_path)
    sim.finish()
    assert lock_files(tmp_path) == []
    assert otmpm.run(short_dyka(), out=out, force=True).status == "ok"


def test_a_simulation_dropped_unfinished_gets_status_interrupted(tmp_path):
    out = str(tmp_path / "r.h5")
    sim = otmpm.Simulation(short_dyka(), out=out)
    sim.step(3)
    del sim
    gc.collect()
    assert status_of(out) == "interrupted"
    assert lock_files(tmp_path) == []


def test_a_simulation_alive_at_interpreter_exit_gets_status_interrupted(tmp_path):
    """Held by a global and by a reference cycle, which the interpreter may never free."""
    code = ("import otmpm, sys\n"
            f"s = otmpm.Scene.from_toml({DYKA!r}, {SHORT!r})\n"
            "sim = otmpm.Simulation(s, out='kept.h5'); sim.step(3)\n"
            "cycle = [otmpm.Simulation(s, out='cycle.h5')]; cycle.append(cycle)\n")
    p = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert status_of(str(tmp_path / "kept.h5")) == "interrupted"
    assert status_of(str(tmp_path / "cycle.h5")) == "interrupted"
    assert lock_files(tmp_path) == []


# ---------------------------------------------------------------- scene values that contain themselves


def test_a_dict_that_contains_itself_is_an_input_error_naming_the_key():
    d = short_dyka().to_dict()
    d["simulation"]["x"] = d
    with pytest.raises(otmpm.InputError, match="simulation.x.*contains itself") as e:
        otmpm.Scene.from_dict(d)
    assert e.value.key == "simulation.x"
    items = [1.0]
    items.append(items)
    with pytest.raises(otmpm.InputError, match="contains itself"):
        short_dyka().with_overrides({"grid.lower": items})


@pytest.mark.parametrize("levels", [257, 200_000])
def test_nesting_deeper_than_the_toml_limit_is_an_input_error(levels):
    x = []
    for _ in range(levels):
        x = [x]
    for make in (lambda: short_dyka().with_overrides({"simulation.t_end": x}),
                 lambda: otmpm.Scene.from_toml(DYKA, overrides={"simulation.t_end": x}),
                 lambda: otmpm.Scene.from_dict({"simulation": {"t_end": x}})):
        with pytest.raises(otmpm.InputError, match="nested deeper than 256 levels"):
            make()


def test_the_same_list_twice_is_no_cycle():
    v = [0.0]
    s = short_dyka().with_overrides({"grid.lower": v, "body.0.velocity": v})
    assert s.to_dict()["grid"]["lower"] == [0.0]


# ---------------------------------------------------------------- override values


def test_override_strings_with_a_line_break_and_values_with_nul_are_refused():
    with pytest.raises(otmpm.InputError, match="line break"):
        short_dyka().with_overrides(["simulation.t_end=1e-5\nsimulation.cfl=5"])
    for value in ("a\x00b.h5", "a\nb.h5"):
        with pytest.raises(otmpm.InputError, match="control character") as e:
            short_dyka().with_overrides({"output.file": value})
        assert e.value.key == "output.file"
    with pytest.raises(otmpm.InputError, match="control character"):
        short_dyka().with_overrides({"output.checkpoint_file": "c\x00k.h5"})


def test_long_arrays_and_strings_with_line_breaks_in_dict_overrides_are_one_value():
    """Dict values are written as TOML on one line (toml++ would break a long array over lines)."""
    fields = ["x", "v", "stress", "strain", "F", "density", "mass", "volume", "displacement"]
    assert otmpm.Scene.from_toml(DYKA, {"output.fields": fields}).to_dict()["output"]["fields"] == fields
    with pytest.raises(otmpm.InputError, match="cannot name a body"):  # the name's own check, not "line break"
        short_dyka().with_overrides({"body.0.name": "two\nlines"})
    name = "it's \"quoted\" \u00e9"
    assert short_dyka().with_overrides({"body.0.name": name}).to_dict()["body"][0]["name"] == name


def test_a_long_name_gives_a_short_message():
    with pytest.raises(otmpm.InputError) as e:
        short_dyka().with_overrides({"material.0.name": "n" * 10_000_000})
    assert len(str(e.value)) < 2000 and "(10000000 bytes)" in str(e.value)
    with pytest.raises(otmpm.InputError) as e:
        otmpm.Scene.from_dict({"simulation": {"t_end": object()}}, name="d" * 1_000_000)
    assert len(str(e.value)) < 2000


# ---------------------------------------------------------------- results.open on other files


def test_results_open_raises_oserror_naming_files_of_other_programs(tmp_path):
    good = str(tmp_path / "good.h5")
    otmpm.run(short_dyka(), out=good)
    with h5py.File(tmp_path / "dataset.h5", "w") as f:
        f["frames"] = [1, 2, 3]
        f.attrs["dimension"] = 1
    cases = {"dataset.h5": None, "dimension.h5": ("", "dimension"), "time.h5": ("frames/000000", "time"),
             "text_dimension.h5": ("", "dimension")}
    for name, change in cases.items():
        path = str(tmp_path / name)
        if change:
            with open(good, "rb") as src, open(path, "wb") as dst:
                dst.write(src.read())
            with h5py.File(path, "a") as f:
                where = f[change[0]] if change[0] else f
                del where.attrs[change[1]]
                where.attrs[change[1]] = "two" if name.startswith("text") else [1, 2]
        with pytest.raises(OSError, match=path):
            with otmpm.results.open(path) as r:
                r.field("x")


def test_results_open_of_a_fifo_or_directory_raises_oserror_at_once(tmp_path):
    os.mkfifo(tmp_path / "fifo.h5")
    code = ("import otmpm.results, sys\n"
            "for p in sys.argv[1:]:\n"
            "    try:\n"
            "        otmpm.results.open(p)\n"
            "    except OSError as e:\n"
            "        print('OSError', e)\n")
    p = subprocess.run([sys.executable, "-c", code, str(tmp_path / "fifo.h5"), str(tmp_path)], capture_output=True,
                       text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert p.stdout.count("OSError") == 2 and "not a regular file" in p.stdout


# ---------------------------------------------------------------- otmpm.basis


@pytest.mark.parametrize("grid, message", [
    (otmpm.basis.Grid([0.0], [1.0], [2e9]), "more than"),
    (otmpm.basis.Grid([0.0] * 3, [1.0] * 3, [1000, 1000, 1000]), "more than"),
    (otmpm.basis.Grid([0.0], [1.0], [10], perturbation=float("nan")), "perturbation"),
    (otmpm.basis.Grid([0.0], [1.0], [10], perturbation=-1), "perturbation"),
    (otmpm.basis.Grid([0.0], [1.0], [10], perturbation=0.5), "perturbation"),
    (otmpm.basis.Grid([0.0], [1.0], [2.7]), "whole number"),
    (otmpm.basis.Grid([0.0], [1.0], [0]), "whole number"),
    (otmpm.basis.Grid([0.0], [1.0], [True]), "number"),
    (otmpm.basis.Grid([0.0], [1.0], ["10"]), "number"),
    (otmpm.basis.Grid([0.0], [1.0], [10], seed=-1), "seed"),
    (otmpm.basis.Grid([float("nan")], [1.0], [10]), "finite"),
    (otmpm.basis.Grid([0.0], [10**400], [10]), "range of a double"),
])
def test_basis_grids_beyond_the_cap_or_with_bad_values_are_input_errors(grid, message):
    with pytest.raises(otmpm.InputError, match=message):
        otmpm.basis.Basis("linear", grid)


def test_a_whole_float_cell_count_is_taken_and_gives_the_int_grid():
    a = otmpm.basis.Basis("linear", otmpm.basis.Grid([0.0], [1.0], [10.0]))
    b = otmpm.basis.Basis("linear", otmpm.basis.Grid([0.0], [1.0], [10]))
    assert np.array_equal(a.nodes, b.nodes) and len(a.nodes) == 11


# ---------------------------------------------------------------- Summary


def test_summary_is_read_only():
    s = otmpm.run(short_dyka(), write_results=False)
    for attempt in (lambda: setattr(s, "steps", 99), lambda: setattr(s, "status", "forged"),
                    lambda: delattr(s, "steps"), lambda: setattr(s, "new_key", 1)):
        with pytest.raises(AttributeError, match="read-only"):
            attempt()
    for mapping in (s.errors, s.phases, s.diagnostics):
        with pytest.raises(TypeError):
            mapping["rms_velocity_error"] = -1
    with pytest.raises(TypeError):
        s["steps"] = 99
    assert s.steps == s["steps"] > 0 and s.status == "ok"
    assert dict(s.errors) == {k: s["errors"][k] for k in s.errors}


# ---------------------------------------------------------------- a run killed inside a flush


def _undo_record(addr, old):
    """One record of otmpm's undo journal: magic, reserved, address, size, CRC-64/XZ check, then the old bytes."""
    import struct

    def crc64(data):  # CRC-64/XZ (ECMA-182, reflected), as the checkpoints' checksum
        crc = 0xFFFFFFFFFFFFFFFF
        for b in data:
            crc ^= b
            for _ in range(8):
                crc = (crc >> 1) ^ (0xC96C5795D7870F42 if crc & 1 else 0)
        return crc ^ 0xFFFFFFFFFFFFFFFF

    magic = 0x524A554F
    check = crc64(struct.pack("<QQQ", magic, addr, len(old)) + old)
    return struct.pack("<IIQQQ", magic, 0, addr, len(old), check) + old


def test_a_result_file_a_kill_cut_inside_a_flush_is_restored_when_opened(tmp_path):
    """As a SIGKILL inside a flush leaves it: bytes already overwritten, their old values in the journal
    (the last record cut short by the kill). otmpm.results.open writes them back and opens the flushed state."""
    out = tmp_path / "r.h5"
    otmpm.run(short_dyka(), out=str(out))
    flushed = out.read_bytes()
    frames = len(otmpm.results.open(str(out)).frames)
    cut = bytearray(flushed)
    cut[0:48] = bytes(48)  # the superblock, half-way through being rewritten
    cut[2048:2600] = b"\xff" * 552
    out.write_bytes(bytes(cut))
    with pytest.raises(OSError):
        h5py.File(out, "r").close()
    journal = tmp_path / ".r.h5.otmpm-undo"
    journal.write_bytes(_undo_record(2048, flushed[2048:2600]) + _undo_record(0, flushed[0:48]) +
                        _undo_record(4096, b"never written")[:20])
    with otmpm.results.open(str(out)) as r:
        assert len(r.frames) == frames
    assert out.read_bytes() == flushed
    assert not journal.exists() and lock_files(tmp_path) == []
