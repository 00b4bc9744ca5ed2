#!/usr/bin/env python3
"""Damaged HDF5 files against every otmpm command that reads them.

Makes real files with the given otmpm - a result file of several frames (and
its checkpoint) and an HDF5 particle file - then damaged copies of each:

  trunc   the file cut at an offset
  zero    a block of bytes set to 0
  flip    a block of bytes inverted (xor 0xff)
  killed  (result files) a run SIGKILLed at a random moment while it writes

and runs every command that reads that kind of file on each copy, in a fresh
folder, under `timeout`. Each run is classified:

  crash    killed by a signal (exit status 128+N or negative)
  hang     still running after --timeout seconds
  garbage  exit 0 where the damaged file had to be refused (a restart that
           copied frames which differ from the undamaged file's)
  message  exit 2 without a message that names the file
  status   an exit status other than 0 and 2 (3: an internal error)
  row      a study that exited 0 but whose CSV row does not say what its
           run did: `study` must record status ok and exit code 0,
           `study-refused` exit code 2 and status `input error: ...`
  ok       a clear refusal (exit 2 naming the file) or a correct success

Commands: for a result file `run` (over it, no --force), `run--force`,
`restart` (from the checkpoint of the run that wrote it, --out another
file), `python` (otmpm.results.open, then every frame's x and v, the probes
and the energy series), `study` and `study-refused` (`otmpm study` of one
run whose result file is the damaged one: in `study` the child `otmpm run
--force` replaces it and the study reads the new file's summary; in
`study-refused` the child is refused - a variant sets simulation.cfl = -1 -
before it touches the file, so the study reads the summary of the damaged
file) and with --render `render`; for a checkpoint
`restart` and `run` (the same scene over its result file, which looks at the
checkpoint beside it); for a particle file `run` and `run--check`. `killed`
also tries tests/scenes/killed_run.h5, the file whose half-written link table
crashed libhdf5. A run that exits 0 on a damaged particle file or result
file is `ok`: damaged raw data reads as other numbers (HDF5 checksums only
its metadata; docs/user-guide.md, "Damaged files").

Usage:
  python3 scripts/h5damage.py build/bin/otmpm [--work DIR] [--stride BYTES]
      [--block BYTES] [--kinds trunc,zero,flip,killed]
      [--types result,checkpoint,particles] [--commands NAME,...]
      [--timeout S] [--kills N] [--seed N] [--render [--scripts DIR]]
      [--results-py FILE] [--quick]

Prints one line per finding and a table of counts by file type x damage kind
x command; exits 1 when anything but `ok` was seen. Damage every --stride
bytes (2048) and densely in the first 1024 (superblock, root group), in
blocks of --block bytes (16). --quick: stride 16384 and 2 kills (about a
minute). The default run takes about 15 minutes on 2 cores.
"""
import argparse
import collections
import os
import random
import shutil
import signal
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SMALL = ["--set", "grid.cells=[15]", "--set", "simulation.t_end=2e-5", "--set", "output.every=1e-6",
         "--threads", "1"]
PARTICLE_SCENE = """
[simulation]
dimension = 1
t_end = 2.0e-6
cfl = 0.1
[basis]
kind = "linear"
[grid]
lower = [-0.01]
upper = [0.11]
cells = [12]
[[material]]
name = "steel"
model = "linear_elastic"
density = 7833.0
young = 200.0e9
poisson = 0.0
[[body]]
material = "steel"
shape = "file"
file = "particles.h5"
[output]
file = "p.h5"
every = 1.0e-6
"""


def run(cmd, cwd, timeout, env=None):
    """(status, stderr): status is 'hang' when it timed out, -N for a signal."""
    try:
        p = subprocess.run(cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, timeout=timeout,
                           env=env)
        return p.returncode, p.stderr.decode(errors="replace")
    except subprocess.TimeoutExpired as e:
        return "hang", (e.stderr or b"").decode(errors="replace")


def classify(status, err, name, zero_ok=True):
    """One of crash, hang, status, message, garbage, ok (see the module doc)."""
    if status == "hang":
        return "hang"
    if status < 0 or status >= 128:
        return "crash"
    if status == 0:
        return "ok" if zero_ok else "garbage"
    if status != 2:
        return "status"
    return "ok" if name in err and ("otmpm: error:" in err or "otmpm render: error:" in err) else "message"


def make_bases(otmpm, work):
    """The undamaged files: base/res.h5 (+ checkpoint), base/particles.h5.

    They are written in case/, the folder every damaged copy is tried in
    (restored from base/ each time): the checkpoint names its result file by
    its absolute path."""
    base = os.path.join(work, "case")
    shutil.rmtree(base, ignore_errors=True)
    os.makedirs(base)
    scene = os.path.join(ROOT, "examples", "dyka.toml")
    # Checkpoint after step 60 of ~120 (frames written before it), so a
    # restart copies frames from the result file.
    subprocess.run([otmpm, "run", scene, "--out", "res.h5", "--force", "--set", "output.checkpoint_every=60"] + SMALL,
                   cwd=base, check=True, stdout=subprocess.DEVNULL)
    # A reference restart from the intact files: its frames are what a
    # restart must copy.
    ref = os.path.join(work, "ref")
    shutil.rmtree(ref, ignore_errors=True)
    os.makedirs(ref)
    pristine = os.path.join(work, "pristine")
    shutil.rmtree(pristine, ignore_errors=True)
    shutil.copytree(base, pristine)
    subprocess.run([otmpm, "run", "--restart", "res.checkpoint.h5", "--out", "again.h5", "--threads", "1"], cwd=base,
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    shutil.move(os.path.join(base, "again.h5"), os.path.join(ref, "again.h5"))
    import h5py
    import numpy as np
    n = 40
    x = (np.arange(n) + 0.5) * (0.1 / n)
    with h5py.File(os.path.join(base, "particles.h5"), "w", libver=("v108", "v108")) as f:
        f["x"] = x.reshape(n, 1)
        f["volume"] = np.full(n, 0.1 / n)
        f["v"] = np.where(x < 0.025, -5.0, 0.0).reshape(n, 1)
        f["density"] = np.full(n, 7833.0)
        for k in range(10):  # enough links for a dense link table
            f[f"state_{k}"] = np.zeros(n)
    with open(os.path.join(base, "particles.toml"), "w") as f:
        f.write(PARTICLE_SCENE)
    shutil.rmtree(pristine)
    shutil.copytree(base, pristine)
    return pristine, ref


def frames_of(path):
    """The frames' datasets of a result file as {name: bytes}, or None when unreadable."""
    code = ("import h5py,sys\nf=h5py.File(sys.argv[1],'r')\nfor k in sorted(f['frames']):\n"
            " for d in sorted(f['frames'][k]):\n  sys.stdout.buffer.write(f['frames'][k][d][()].tobytes())\n")
    p = subprocess.run([sys.executable, "-c", code, path], capture_output=True, timeout=60)
    return p.stdout if p.returncode == 0 else None


def damaged(data, kind, offset, block):
    if kind == "trunc":
        return data[:offset]
    b = bytearray(data)
    end = min(len(b), offset + block)
    for i in range(offset, end):
        b[i] = 0 if kind == "zero" else b[i] ^ 0xFF
    return bytes(b)


def offsets(size, stride, rng):
    """Every stride bytes (from a random phase), and the first 1024 bytes (superblock, root group) densely."""
    first = list(range(0, min(size, 1024), max(8, stride // 8)))
    return sorted(set(first + list(range(rng.randrange(stride), size, stride))))


class Matrix:
    def __init__(self):
        self.counts = collections.defaultdict(collections.Counter)
        self.findings = []

    def add(self, ftype, kind, command, verdict, detail):
        self.counts[(ftype, kind, command)][verdict] += 1
        if verdict != "ok":
            self.findings.append(f"{verdict:8s} {ftype}/{kind}/{command}: {detail}")
            print(self.findings[-1], flush=True)

    def table(self):
        verdicts = ["ok", "crash", "hang", "garbage", "message", "status", "row"]
        lines = [f"{'file':11s} {'damage':7s} {'command':16s} " + " ".join(f"{v:>7s}" for v in verdicts)]
        for key in sorted(self.counts):
            c = self.counts[key]
            lines.append(f"{key[0]:11s} {key[1]:7s} {key[2]:16s} " + " ".join(f"{c[v]:7d}" for v in verdicts))
        return "\n".join(lines)


#: The study of the `study` commands: one run, variant {variant}, mesh m,
#: its result file study_results/{variant}_m.h5 (where the damaged file goes).
STUDY = """scene = "{scene}"
csv = "study.csv"
results = "study_results"
jobs = 1
set = ["grid.cells=[15]", "simulation.t_end=2e-5", "output.every=1e-6"]
[[variant]]
name = "{variant}"
set = [{sets}]
[[mesh]]
name = "m"
h = 0.01
"""
#: The `study` commands: name -> (variant, its set entries, the CSV row's expected exit code, status prefix).
STUDIES = {
    "study": ("v", "", "0", "ok"),
    "study-refused": ("refused", '"simulation.cfl=-1"', "2", "input error: "),
}


def study_argv(otmpm, name):
    """The `otmpm study` of the command `name` (its study file: write_study); no plots (--scripts: no such folder)."""
    return [otmpm, "study", name + ".toml", "--threads", "1", "--scripts", "no-scripts"]


def write_study(case, name):
    """Writes the study file of the command `name` in `case` and puts the damaged res.h5 where its run writes."""
    variant, sets, _, _ = STUDIES[name]
    with open(os.path.join(case, name + ".toml"), "w") as f:
        f.write(STUDY.format(scene=os.path.join(ROOT, "examples", "dyka.toml"), variant=variant, sets=sets))
    os.makedirs(os.path.join(case, "study_results"), exist_ok=True)
    shutil.copy(os.path.join(case, "res.h5"), os.path.join(case, "study_results", variant + "_m.h5"))


def study_row_verdict(case, name):
    """'ok' when the study's CSV has the row of its run with the exit code and status it must have, else 'row'."""
    import csv
    variant, _, exit_code, status = STUDIES[name]
    try:
        with open(os.path.join(case, "study.csv"), newline="") as f:
            rows = [r for r in csv.DictReader(f) if r["variant"] == variant]
    except OSError:
        rows = []
    ok = len(rows) == 1 and rows[0]["exit_code"] == exit_code and rows[0]["status"].startswith(status)
    return "ok" if ok else "row", (rows[0]["exit_code"], rows[0]["status"][:80]) if rows else "no row"


def result_commands(otmpm, render_python, results_py, scripts=None):
    """(name, argv in the case folder, exit 0 acceptable) for a damaged result file res.h5."""
    scene = os.path.join(ROOT, "examples", "dyka.toml")
    cmds = [
        ("run", [otmpm, "run", scene, "--out", "res.h5"] + SMALL, True),
        ("run--force", [otmpm, "run", scene, "--out", "res.h5", "--force"] + SMALL, True),
        # The interrupted run's result file is res.h5 (an absolute path in
        # the checkpoint: each case restarts in its own copy of base/).
        ("restart", [otmpm, "run", "--restart", "res.checkpoint.h5", "--out", "again.h5", "--threads", "1"], True),
        ("python", [sys.executable, "-c",
                    "import importlib.util as u, sys; s = u.spec_from_file_location('results', sys.argv[2])\n"
                    "R = u.module_from_spec(s); s.loader.exec_module(R)\n"
                    "try:\n r = R.open(sys.argv[1]); [r.field(n) for n in ('x','v')]; r.probes; r.energy\n"
                    "except Exception as e: print('otmpm: error: res.h5: ', e, file=sys.stderr); sys.exit(2)\n",
                    "res.h5", results_py], True),
    ] + [(name, study_argv(otmpm, name), True) for name in STUDIES]
    if render_python:
        cmds.append(("render", [otmpm, "render", "res.h5", "--field", "v", "--frame", "-1", "--out", "r.png"] +
                     (["--scripts", scripts] if scripts else []), True))
    return cmds


def check_result_case(m, otmpm, case, kind, detail, data, args, base, ref_frames):
    """Runs the result file commands on base/ with res.h5 replaced by `data` (None: as it is)."""
    for name, argv, zero_ok in result_commands(otmpm, args.render, args.results_py, args.scripts):
        if args.commands and name not in args.commands:
            continue
        shutil.rmtree(case, ignore_errors=True)
        shutil.copytree(base, case)
        if data is not None:
            with open(os.path.join(case, "res.h5"), "wb") as f:
                f.write(data)
        if name == "restart" and not os.path.exists(os.path.join(case, "res.checkpoint.h5")):
            continue
        if name in STUDIES:
            write_study(case, name)
        status, err = run(argv, case, args.timeout)
        verdict = classify(status, err, "res.h5", zero_ok)
        if verdict == "ok" and name in STUDIES:
            verdict, row = study_row_verdict(case, name)
            err += f" (CSV row: {row})"
        if verdict == "ok" and name == "restart" and status == 0 and ref_frames is not None:
            # A restart that succeeded must have copied the frames intact.
            got = frames_of(os.path.join(case, "again.h5"))
            if got != ref_frames:
                verdict = "garbage"
        m.add("result", kind, name, verdict, f"{detail} -> {status} {err.strip()[-200:]!r}")


def check_copy(m, otmpm, case, ftype, kind, detail, data, args):
    if ftype == "checkpoint":
        cmds = [("restart", [otmpm, "run", "--restart", "res.checkpoint.h5", "--out", "again.h5", "--threads", "1"],
                 "res.checkpoint.h5", "res.checkpoint.h5", False),
                # The scene of res.h5: the damaged checkpoint beside it is the question.
                ("run", [otmpm, "run", os.path.join(ROOT, "examples", "dyka.toml"), "--out", "res.h5",
                         "--set", "output.checkpoint_every=60"] + SMALL,
                 "res.checkpoint.h5", "res.checkpoint.h5", True)]
    else:
        cmds = [("run", [otmpm, "run", "particles.toml", "--threads", "1"], "particles.h5", "particles.h5", True),
                ("run--check", [otmpm, "run", "particles.toml", "--check"], "particles.h5", "particles.h5", True)]
    for name, argv, target, shown, zero_ok in cmds:
        if args.commands and name not in args.commands:
            continue
        shutil.rmtree(case, ignore_errors=True)
        shutil.copytree(args.base, case)
        with open(os.path.join(case, target), "wb") as f:
            f.write(data)
        status, err = run(argv, case, args.timeout)
        # A damaged checkpoint must be refused; particle data damage may read
        # as other valid numbers (HDF5 keeps no checksum of raw data), which
        # the scene's checks may refuse naming the body of the scene file.
        verdict = classify(status, err, shown, zero_ok or data == open(os.path.join(args.base, target), "rb").read())
        if verdict == "message" and ftype == "particles":
            verdict = classify(status, err, "particles.toml")
        m.add(ftype, kind, name, verdict, f"{detail} -> {status} {err.strip()[-200:]!r}")


def killed_runs(otmpm, case, work, n, rng):
    """Folders left by runs SIGKILLed at random moments while they write
    their result file and checkpoints (yields each, copied to work/killed)."""
    scene = os.path.join(ROOT, "examples", "dyka.toml")
    kept = os.path.join(work, "killed")
    argv = [otmpm, "run", scene, "--out", "res.h5", "--threads", "1", "--set", "grid.cells=[40]",
            "--set", "simulation.t_end=1e-4", "--set", "output.every=2e-7", "--set", "output.checkpoint_every=100"]
    # How long the whole run takes: the kills fall anywhere in it, the
    # final summary attributes included.
    shutil.rmtree(case, ignore_errors=True)
    os.makedirs(case)
    start = time.monotonic()
    subprocess.run(argv, cwd=case, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    duration = time.monotonic() - start
    for i in range(n):
        shutil.rmtree(case, ignore_errors=True)
        os.makedirs(case)
        p = subprocess.Popen(argv, cwd=case, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        delay = rng.uniform(0.02, 1.02 * duration)
        time.sleep(delay)
        p.send_signal(signal.SIGKILL)
        p.wait()
        if os.path.exists(os.path.join(case, "res.h5")):
            shutil.rmtree(kept, ignore_errors=True)
            shutil.copytree(case, kept)
            yield f"kill #{i} after {delay:.2f} s", kept


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("otmpm")
    ap.add_argument("--work", default="/tmp/h5damage")
    ap.add_argument("--stride", type=int, default=2048)
    ap.add_argument("--block", type=int, default=16)
    ap.add_argument("--kinds", default="trunc,zero,flip,killed")
    ap.add_argument("--types", default="result,checkpoint,particles")
    ap.add_argument("--commands", default="")
    ap.add_argument("--timeout", type=float, default=20)
    ap.add_argument("--kills", type=int, default=10)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--render", action="store_true", help="also otmpm render (slow: matplotlib)")
    ap.add_argument("--scripts", help="otmpm render --scripts DIR (render.py; default: beside the binary)")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--results-py", default=os.path.join(ROOT, "python", "otmpm", "results.py"),
                    help="the otmpm.results module to try (default: this tree's)")
    args = ap.parse_args()
    if args.quick:
        args.stride, args.kills = 16384, 2
    args.commands = [c for c in args.commands.split(",") if c]
    otmpm = os.path.abspath(args.otmpm)
    rng = random.Random(args.seed)
    os.makedirs(args.work, exist_ok=True)
    args.base, ref = make_bases(otmpm, args.work)
    ref_frames = frames_of(os.path.join(ref, "again.h5"))
    case = os.path.join(args.work, "case")
    m = Matrix()
    kinds = args.kinds.split(",")
    files = {"result": "res.h5", "checkpoint": "res.checkpoint.h5", "particles": "particles.h5"}
    for ftype in args.types.split(","):
        with open(os.path.join(args.base, files[ftype]), "rb") as f:
            data = f.read()
        copies = []
        for kind in kinds:
            if kind == "killed":
                continue
            for off in offsets(len(data), args.stride, rng):
                copies.append((kind, f"{files[ftype]} {kind} at {off} of {len(data)}",
                               damaged(data, kind, off, args.block)))
        for kind, detail, d in copies:
            if ftype == "result":
                check_result_case(m, otmpm, case, kind, detail, d, args, args.base, ref_frames)
            else:
                check_copy(m, otmpm, case, ftype, kind, detail, d, args)
        if ftype == "result" and "killed" in kinds:
            for detail, folder in killed_runs(otmpm, case, args.work, args.kills, rng):
                check_result_case(m, otmpm, case, "killed", detail, None, args, folder, None)
            # The file a killed run of the study test left (its half-written
            # link table crashed libhdf5): checked against the intact base/.
            with open(os.path.join(ROOT, "tests", "scenes", "killed_run.h5"), "rb") as f:
                check_result_case(m, otmpm, case, "killed", "tests/scenes/killed_run.h5", f.read(), args, args.base,
                                  None)
    print(m.table())
    bad = sum(c[v] for c in m.counts.values() for v in c if v != "ok")
    print(f"{bad} findings")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
