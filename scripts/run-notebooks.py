#!/usr/bin/python3
"""Executes the Jupyter notebooks of examples/notebooks/ headless (nbclient,
Debian's python3-nbclient and python3-ipykernel), so that they cannot go
stale: a cell that raises fails the run (exit 1, the cell and its error
printed). The notebooks are read, not rewritten: their outputs stay out of
the repository.

    /usr/bin/python3 scripts/run-notebooks.py [NOTEBOOK.ipynb ...]

The kernel is this interpreter; the otmpm package must be importable
(installed with pip, or PYTHONPATH=build/python). OTMPM_SOURCE_DIR is set to
this source tree for the notebooks' paths of the examples.
"""
import glob
import os
import sys
import time

import nbclient
import nbformat

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main(paths):
    paths = paths or sorted(glob.glob(os.path.join(ROOT, "examples", "notebooks", "*.ipynb")))
    if not paths:
        sys.exit("no notebook found")
    os.environ.setdefault("OTMPM_SOURCE_DIR", ROOT)
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
