#!/usr/bin/python3
"""Executes the Jupyter notebooks of examples/notebooks/ headless (nbclient,
Debian's python3-nbclient and python3-ipykernel), so that they cannot go
stale: a cell that raises fails the run (exit 1, the cell and its error
printed). The notebooks are read, not rewritten: their outputs stay out of
the repository.

    /usr/bin/python3 scripts/run-notebooks.py [NOTEBOOK.ipynb ...]

The kernel is this interpreter (a kernel spec of its own, found first
through JUPYTER_PATH); the otmpm package must be importable
(installed with pip, or PYTHONPATH=build/python). OTMPM_SOURCE_DIR is set to
this source tree for the notebooks' paths of the examples.
"""
import glob
import json
import os
import sys
import tempfile
import time

import nbclient
import nbformat

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main(paths):
    paths = paths or sorted(glob.glob(os.path.join(ROOT, "examples", "notebooks", "*.ipynb")))
    if not paths:
        sys.exit("no notebook found")
    os.environ.setdefault("OTMPM_SOURCE_DIR", ROOT)
    # the kernel: this interpreter (a venv's, with the package it installed),
    # not the system's kernel spec, which would start /usr/bin/python3
    specs = tempfile.mkdtemp(prefix="otmpm-kernels-")
    os.makedirs(os.path.join(specs, "kernels", "python3"))
    with open(os.path.join(specs, "kernels", "python3", "kernel.json"), "w") as f:
        json.dump({"argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
                   "display_name": "Python 3", "language": "python"}, f)
    os.environ["JUPYTER_PATH"] = specs + os.pathsep + os.environ.get("JUPYTER_PATH", "")
    os.environ.setdefault("MPLBACKEND", "Agg")
    os.environ.setdefault("PYDEVD_DISABLE_FILE_VALIDATION", "1")  # the kernel's debugger notes on stderr
    for path in paths:
        nb = nbformat.read(path, as_version=4)
        start = time.time()
        client = nbclient.NotebookClient(nb, timeout=600, kernel_name="python3",
                                         resources={"metadata": {"path": os.path.dirname(os.path.abspath(path))}})
        try:
            client.execute()
        except nbclient.exceptions.CellExecutionError as e:
            print(f"FAILED: {path}:\n{e}", file=sys.stderr)
            return 1
        cells = sum(1 for c in nb.cells if c.cell_type == "code")
        print(f"ok: {os.path.relpath(path, ROOT)}: {cells} code cells in {time.time() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
