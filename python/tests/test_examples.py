"""The examples of examples/python run as a user runs them (each under a
minute), with their plots written into a temporary folder."""
import os
import re
import subprocess
import sys
import time

import pytest

from conftest import SOURCE

EXAMPLES = SOURCE / "examples" / "python"


def run_example(name, out):
    start = time.perf_counter()
    done = subprocess.run([sys.executable, str(EXAMPLES / name), "--out", str(out)], capture_output=True, text=True,
                          env={**os.environ, "MPLBACKEND": "Agg"})
    assert done.returncode == 0, done.stderr
    print(f"{name}: {time.perf_counter() - start:.1f} s")
    return done.stdout


def png(path):
    """True when `path` is a non-trivial PNG file."""
    with open(path, "rb") as f:
        return f.read(8) == b"\x89PNG\r\n\x1a\n" and os.path.getsize(path) > 10_000


def test_dyka_pair(tmp_path):
    out = run_example("dyka_pair.py", tmp_path)
    assert re.search(r"^status\s+ok\s+ok$", out, re.M), out
    errors = [float(x) for x in re.search(r"^history_error_A\s+(\S+)\s+(\S+)$", out, re.M).groups()]
    assert all(0.3 < e < 0.7 for e in errors)  # docs/benchmarks.md: about 0.5 m/s at h = L/133
    assert png(tmp_path / "dyka_pair_history.png")
    assert (tmp_path / "dyka_pair_mpm.h5").exists() and (tmp_path / "dyka_pair_ul.h5").exists()


def test_gamma_sweep(tmp_path):
    out = run_example("gamma_sweep.py", tmp_path)
    rows = re.findall(r"gamma_lme = +(\S+) +h = L/(\d+) +ok .* rms_velocity_error = (\S+) m/s", out)
    assert len(rows) == 18
    by_gamma = {}
    for gamma, mesh, error in rows:
        by_gamma.setdefault(gamma, []).append(float(error))
    for errors in by_gamma.values():  # finer meshes give smaller errors, for every gamma_lme
        assert errors == sorted(errors, reverse=True)
    assert png(tmp_path / "gamma_sweep_work_precision.png")


def test_wave_front(tmp_path):
    out = run_example("wave_front.py", tmp_path)
    measured, c = map(float, re.search(r"measured (\S+) m/s, c = sqrt\(E/rho\) = (\S+) m/s", out).groups())
    assert measured == pytest.approx(c, rel=0.02)
    assert png(tmp_path / "wave_front.png")
