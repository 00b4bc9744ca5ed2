"""Shared fixtures of the Python tests (run by ctest: python/CMakeLists.txt
sets PYTHONPATH to the built package, OTMPM_SOURCE_DIR and OTMPM_CLI; CI
runs them against the package installed with pip, and its command)."""
import os
import pathlib
import subprocess

import pytest

SOURCE = pathlib.Path(os.environ.get("OTMPM_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
def _cli():
    """$OTMPM_CLI, else the command of the package under test (built, or installed with pip)."""
    if os.environ.get("OTMPM_CLI"):
        return os.environ["OTMPM_CLI"]
    from otmpm import _config

    return _config.cli_path()


CLI = _cli()


def example(name):
    """The path of a file under examples/."""
    return str(SOURCE / "examples" / name)


def run_cli(*args, cwd=None):
    """Runs the otmpm command; returns the CompletedProcess (text output)."""
    return subprocess.run([CLI, *map(str, args)], capture_output=True, text=True, cwd=cwd)


@pytest.fixture
def source():
    return SOURCE
