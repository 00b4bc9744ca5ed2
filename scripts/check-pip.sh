#!/usr/bin/env bash
# `pip install .` as a user would, offline, with Debian's packages alone
# (scripts/install-deps.sh): into a fresh venv made with
# --system-site-packages (NumPy, h5py, matplotlib, pytest from Debian), then
# `import otmpm` from another folder, the Python tests and the notebooks
# against the installed package (and its own otmpm command); then
# `pip install --user` into a throw-away home (Debian 12's pip needs
# --break-system-packages for --user: its Python is "externally managed").
# The CMake build goes to build-pip in the source tree (setup.py): a second
# install rebuilds only what changed. OTMPM_CMAKE_ARGS passes CMake options
# (CI: the main build's, so that ccache serves the compiled files).
# Usage: bash scripts/check-pip.sh
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d /tmp/otmpm-pip.XXXXXX)
trap 'rm -rf "$work"' EXIT
python=/usr/bin/python3

echo "-- venv: pip install --no-build-isolation --no-index ."
"$python" -m venv --system-site-packages "$work/venv"
"$work/venv/bin/pip" install --no-build-isolation --no-index "$root"
cd "$work"
"$work/venv/bin/python" - "$root" <<'PY'
import os, subprocess, sys
import otmpm
from otmpm import _config
root = sys.argv[1]
assert not otmpm.__file__.startswith(root), f"otmpm imported from the source tree: {otmpm.__file__}"
cli = _config.cli_path()
version = subprocess.run([cli, "--version"], capture_output=True, text=True, check=True).stdout.strip()
print(f"ok: import otmpm {otmpm.__version__} from {os.path.dirname(otmpm.__file__)} (cwd {os.getcwd()}); its command: {version}")
PY

echo "-- the Python tests against the installed package"
OTMPM_SOURCE_DIR=$root MPLBACKEND=Agg "$work/venv/bin/python" -m pytest -q -p no:cacheprovider "$root/python/tests"

echo "-- the notebooks (examples/notebooks), executed headless with the installed package"
"$work/venv/bin/python" "$root/scripts/run-notebooks.py"

echo "-- pip install --user (a throw-away HOME)"
HOME="$work/home" "$python" -m pip install --user --break-system-packages --no-build-isolation --no-index -q "$root"
HOME="$work/home" "$python" -c "
import otmpm
assert otmpm.__file__.startswith('$work/home/'), otmpm.__file__
print('ok: pip install --user:', otmpm.__file__)"
