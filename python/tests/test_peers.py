"""bench/peers/compare_peer.py: the figures of an otmpm result against a
particle dump of another code (the LAMMPS text form Karamelo writes)."""
import subprocess
import sys

import h5py
import numpy as np

from conftest import SOURCE, run_cli

SCRIPT = SOURCE / "bench" / "peers" / "compare_peer.py"
BLOCK = SOURCE / "bench" / "peers" / "block_2d.toml"


def small_block(tmp_path):
    """The peers' block on a 20 x 20 grid for 10 steps; returns the result's path."""
    out = tmp_path / "block.h5"
    done = run_cli("run", BLOCK, "--quiet", "--out", out, "--set", "grid.lower=[-0.1, 0.0]",
                   "--set", "grid.upper=[1.1, 1.1]", "--set", "grid.cells=[24, 22]",
                   "--set", "boundary.base.lower=[-0.1, 0.0]", "--set", "boundary.base.upper=[1.1, 0.0]",
                   "--set", "simulation.dt=1e-4", "--set", "simulation.t_end=1e-3",
                   "--set", 'output.fields=["x", "v", "stress"]')
    assert done.returncode == 0, done.stderr
    return out


def write_dump(path, columns):
    """A LAMMPS-style dump of one frame: `ITEM: ATOMS` and the column names."""
    names = list(columns)
    n = len(columns[names[0]])
    lines = ["ITEM: TIMESTEP", "10", "ITEM: NUMBER OF ATOMS", str(n), "ITEM: BOX BOUNDS sm sm sm",
             "-0.1 1.1", "0 1.1", "0 0", "ITEM: ATOMS " + " ".join(names)]
    lines += [" ".join(repr(float(columns[k][i])) for k in names) for i in range(n)]
    path.write_text("\n".join(lines) + "\n")


def dump_of(result, path, order, vy_factor=1.0):
    """The last frame of `result` as a dump, its particles in `order`."""
    with h5py.File(result, "r") as f:
        frames = f["frames"]
        last = frames[sorted(frames)[-1]]
        x, v, s = (np.array(last[k])[order] for k in ("x", "v", "stress"))
    n = len(x)
    write_dump(path, {"id": np.arange(1, n + 1), "type": np.ones(n), "x": x[:, 0], "y": x[:, 1],
                      "vx": v[:, 0], "vy": vy_factor * v[:, 1], "s11": s[:, 0], "s22": s[:, 3], "s12": s[:, 1]})


def figures(result, dump):
    """compare_peer.py's rows: {figure: (otmpm, peer, relative difference)}."""
    done = subprocess.run([sys.executable, str(SCRIPT), "block", str(result), str(dump)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    rows = {}
    for line in done.stdout.splitlines()[1:]:
        *name, a, b, d = line.split()
        rows[" ".join(name)] = (float(a), float(b), float(d))
    return rows


def test_the_same_particles_in_another_order_give_the_same_figures(tmp_path):
    result = small_block(tmp_path)
    with h5py.File(result, "r") as f:
        n = len(f["frames"]["000000"]["x"])
    dump = tmp_path / "dump.txt"
    dump_of(result, dump, np.random.default_rng(1).permutation(n))
    rows = figures(result, dump)
    assert rows["particles"][:2] == (n, n)
    for name, (a, b, d) in rows.items():
        # a mean over the particles in another order: equal to a few ulps
        assert abs(d) <= 1e-13, name
    assert rows["mean sigma_yy below y = 0.1 m [Pa]"][0] < 0.0  # the block rests on its base


def test_a_changed_velocity_shows_as_its_relative_size(tmp_path):
    result = small_block(tmp_path)
    with h5py.File(result, "r") as f:
        n = len(f["frames"]["000000"]["x"])
    dump = tmp_path / "dump.txt"
    dump_of(result, dump, np.arange(n), vy_factor=1.001)
    rows = figures(result, dump)
    # (peer - otmpm) / |otmpm| of a negative mean made 0.1% larger, printed to 3 digits
    assert abs(rows["mean vy [m/s]"][2] + 1e-3) < 1e-5
    assert abs(rows["mean vy below y = 0.1 m [m/s]"][2] + 1e-3) < 1e-5
    assert rows["mean sigma_yy below y = 0.1 m [Pa]"][2] == 0.0


def test_a_dump_without_particles_is_refused_naming_the_file(tmp_path):
    result = small_block(tmp_path)
    dump = tmp_path / "empty.txt"
    dump.write_text("ITEM: TIMESTEP\n0\n")
    done = subprocess.run([sys.executable, str(SCRIPT), "block", str(result), str(dump)],
                          capture_output=True, text=True)
    assert done.returncode != 0
    assert str(dump) in done.stderr and "ITEM: ATOMS" in done.stderr
