#!/usr/bin/env bash
# Builds otmpm with warnings as errors and runs every test (ctest).
# Usage: bash scripts/test.sh            (from any directory; installs Debian packages if missing)
# OTMPM_CTEST_ARGS adds ctest options (CI: -LE python, the Python tests run
# against the pip-installed package instead: scripts/check-pip.sh).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bash "$root/scripts/install-deps.sh"
build=${OTMPM_BUILD_DIR:-$root/build}
jobs=$(nproc 2>/dev/null || echo 2)
echo "== building otmpm and its tests in $build (only what scripts/main-job.sh or an earlier build did not)"
bash "$root/scripts/configure.sh" "$build"
cmake --build "$build" -j"$jobs"
# Tests run side by side (ctest -j): OpenMP threads must sleep, not spin, while waiting.
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
# shellcheck disable=SC2086
ctest --test-dir "$build" --output-on-failure -j"$jobs" ${OTMPM_CTEST_ARGS:-}
