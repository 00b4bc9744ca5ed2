"""Shared fixtures of the Python tests (run by ctest: python/CMakeLists.txt
sets PYTHONPATH to the built package, OTMPM_SOURCE_DIR and OTMPM_CLI)."""
import os
import pathlib
import subprocess

import pytest

SOURCE = pathlib.Path(os.environ.get("OTMPM_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
CLI = os.environ.get("OTMPM_CLI", str(SOURCE / "build" / "bin" / "otmpm"))


def example(name):
    """The path of a file under examples/."""
    return str(SOURCE / "examples" / name)


def run_cli(*args, cwd=None):
    """Runs the otmpm command; returns the CompletedProcess (text output)."""
    return subprocess.run([CLI, *map(str, args)], capture_output=True, text=True, cwd=cwd)


@pytest.fixture
def source():
    return SOURCE
