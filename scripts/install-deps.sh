#!/usr/bin/env bash
# Installs otmpm's build, test and plotting dependencies from Debian packages.
# Idempotent: safe to run again; does nothing when everything is present.
# With arguments, installs those packages instead (scripts/fuzz.sh: clang).
#
# The ParaView client test (ctest label "client", tests/client/) needs
# ParaView (paraview, python3-paraview: pvpython and pvbatch), xvfb to render
# without a display, and python3-meshio. ParaView is the heavy part (about 170
# packages, 80 MB to download); set OTMPM_NO_PARAVIEW=1 to leave it (and xvfb)
# out - the client test is then reported as skipped.
set -euo pipefail
pkgs=(
  build-essential cmake pkg-config
  libeigen3-dev libboost-dev libhdf5-dev hdf5-tools
  libtomlplusplus-dev doctest-dev libcli11-dev doxygen
  python3 python3-matplotlib python3-h5py python3-numpy python3-meshio
)
if [ -z "${OTMPM_NO_PARAVIEW:-}" ]; then
  pkgs+=(paraview python3-paraview xvfb xauth)
fi
[ $# -gt 0 ] && pkgs=("$@")
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
