"""otmpm.results on damaged result files (docs/user-guide.md, "Damaged files").

tests/scenes/killed_run.h5 was left by a SIGKILLed run: its /frames group
records 206 links and holds 205. Listing it in name order (h5py's
`for name in group`) crashed the interpreter inside libhdf5; the reader walks
the name index instead and warns. A truncated copy and one with a metadata
block inverted raise OSError naming the file, never a crash (each case runs
in a child interpreter so that a crash is seen as one).
"""
import shutil
import subprocess
import sys

import pytest

READ = """
import sys, warnings
import otmpm.results
warnings.simplefilter("error" if sys.argv[2] == "strict" else "default")
try:
    r = otmpm.results.open(sys.argv[1])
    print(len(r.frames), r.field("v").shape, sorted(r.probes), sorted(r.energy), r.status)
except (OSError, RuntimeWarning) as e:
    print(type(e).__name__, e)
    sys.exit(2)
"""


def read(path, mode="default"):
    return subprocess.run([sys.executable, "-c", READ, str(path), mode], capture_output=True, text=True, timeout=120)


@pytest.fixture
def killed(source, tmp_path):
    path = tmp_path / "killed.h5"
    shutil.copy(source / "tests" / "scenes" / "killed_run.h5", path)
    return path


def test_killed_run_frames_are_read_with_a_warning(killed):
    p = read(killed)
    assert p.returncode == 0, p.stderr
    assert p.stdout.split("(")[0].strip() == "205"  # the frames the index holds
    assert "(205, 26, 1)" in p.stdout
    assert "group /frames records 206 links but holds 205" in p.stderr
    # The warning is a RuntimeWarning naming the file (an error when asked for).
    strict = read(killed, "strict")
    assert strict.returncode == 2
    assert strict.stdout.startswith(f"RuntimeWarning {killed}: group /frames records 206 links")


def test_damaged_copies_raise_oserror_naming_the_file(killed, tmp_path):
    data = killed.read_bytes()
    truncated = tmp_path / "truncated.h5"
    truncated.write_bytes(data[: len(data) // 2])
    p = read(truncated)
    assert p.returncode == 2, (p.returncode, p.stderr)
    assert p.stdout.startswith(f"OSError {truncated}: cannot open it as a result file")
    # Inverted bytes across the file: each copy reads or raises OSError (no crash).
    outcomes = set()
    for at in range(0, len(data), len(data) // 10):
        damaged = bytearray(data)
        for i in range(at, min(at + 16, len(data))):
            damaged[i] ^= 0xFF
        copy = tmp_path / f"flip{at}.h5"
        copy.write_bytes(bytes(damaged))
        p = read(copy)
        assert p.returncode in (0, 2), (at, p.returncode, p.stderr[-500:])
        if p.returncode == 2:
            assert p.stdout.startswith(f"OSError {copy}: "), p.stdout
        outcomes.add(p.returncode)
        copy.unlink()
    assert outcomes == {0, 2}  # some damage hits raw data (read as other numbers), some metadata
