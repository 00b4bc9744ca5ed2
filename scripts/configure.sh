#!/usr/bin/env bash
# Configures the build folder of scripts/test.sh and scripts/main-job.sh with
# the one set of options both use (Release, warnings as errors), so that
# neither rebuilds what the other built.
# Usage: bash scripts/configure.sh BUILD_DIR [more cmake options]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=$1
shift
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release -DOTMPM_WERROR=ON "$@"
