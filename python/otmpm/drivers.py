"""otmpm.pair and otmpm.study: the `otmpm pair` and `otmpm study` commands from Python."""
import csv
import os
import subprocess
import sys
import tomllib

from . import _config, _otmpm

#: The two node modes `pair` runs.
MODES = ("mpm", "ul")


def pair_out_file(out, mode):
    """The result file of one run of a pair: `out` with _MODE inserted before .h5 (as `otmpm pair`)."""
    i = out.rfind(".h5")
    return (out if i < 0 else out[:i]) + "_" + mode + ".h5"


def pair(scene, threads=None, force=False):
    """Runs the scene with simulation.mode = "mpm" and "ul" (same basis and integrator), as `otmpm pair`.

    Returns {"mpm": Summary, "ul": Summary}. The result files are the scene's
    output.file with _mpm and _ul before .h5. Each run goes through otmpm.run
    (the library, GIL released, Ctrl-C -> KeyboardInterrupt), so the results
    are those of the command line, bit for bit. force=True replaces existing
    result files (`otmpm pair --force`).
    """
    runs = {}
    for mode in MODES:
        s = scene.with_overrides({"simulation.mode": mode})
        runs[mode] = _otmpm.run(s, out=pair_out_file(s.output_file, mode), threads=threads,
                                 force=force)
    return runs


class StudyResult:
    """What otmpm.study returns: csv (the CSV file's path) and rows (one dict per run, numbers as float)."""

    def __init__(self, csv_path, rows):
        self.csv = csv_path
        self.rows = rows

    def __repr__(self):
        return f"<otmpm.StudyResult {self.csv}: {len(self.rows)} rows>"


def _number(text):
    """A CSV cell as a float when it is one, else the text."""
    try:
        return float(text)
    except ValueError:
        return text


def study_csv(path):
    """The CSV file of a study file: its `csv` key relative to the study file (default: STEM.csv)."""
    with open(path, "rb") as f:
        study = tomllib.load(f)
    stem = os.path.splitext(os.path.basename(path))[0]
    return os.path.join(os.path.dirname(os.path.abspath(path)), study.get("csv", stem + ".csv"))


def study(path):
    """Runs `otmpm study PATH` (the command line: each run is a child process, `jobs` at a
    time; rows already in the CSV are skipped) and returns a StudyResult with the CSV's rows.

    The command's output is copied to sys.stdout as it comes. Bad input (exit status 2) raises
    otmpm.InputError with the command's message; another failure RuntimeError.
    The command is $OTMPM_CLI, else the otmpm built or installed with this package.
    """
    cli = _config.cli_path()
    with subprocess.Popen([cli, "study", os.fspath(path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          text=True, bufsize=1) as child:
        for line in child.stdout:  # through sys.stdout, so that notebooks and doctest see it
            sys.stdout.write(line)
        stderr = child.stderr.read()
    sys.stderr.write(stderr)
    if child.returncode == 2:
        raise _otmpm.InputError(stderr.strip().removeprefix("otmpm: error: "))
    if child.returncode != 0:
        raise RuntimeError(f"{cli} study {path}: exit status {child.returncode}: {stderr.strip()}")
    csv_path = study_csv(path)
    with open(csv_path, newline="") as f:
        rows = [{k: _number(v) for k, v in row.items()} for row in csv.DictReader(f)]
    return StudyResult(csv_path, rows)
