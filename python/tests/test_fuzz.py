"""The Python API fuzzer (fuzz_api.py) with fixed seeds and a bounded number
of iterations: random call sequences on Scene, Simulation, otmpm.results and
otmpm.basis objects, each call's outcome one that the docs promise, no crash,
no call longer than fuzz_api.CALL_SECONDS, no result file left "running", no
lock file left. Each seed runs in a child interpreter so that a crash is seen
as one (with the last call printed); about 7 s in all. scripts/fuzz.sh runs
the same fuzzer with a new seed every time."""
import os
import pathlib
import subprocess
import sys

import pytest

FUZZER = pathlib.Path(__file__).with_name("fuzz_api.py")
#: Seeds and iterations per seed: 4 x 150 iterations, about 3000 calls.
SEEDS = (1, 2, 3, 4)
ITERATIONS = 150


@pytest.mark.parametrize("seed", SEEDS)
def test_api_fuzzer_finds_nothing(seed, tmp_path):
    env = dict(os.environ, OMP_NUM_THREADS="1")
    p = subprocess.run([sys.executable, str(FUZZER), "--seed", str(seed), "--iterations", str(ITERATIONS),
                        "--workdir", str(tmp_path)], capture_output=True, text=True, env=env, timeout=600)
    tail = "\n".join(p.stdout.splitlines()[-15:])
    assert p.returncode == 0, f"exit status {p.returncode}\n{tail}\n{p.stderr[-3000:]}"
    assert f"no finding in {ITERATIONS} iterations" in p.stdout
