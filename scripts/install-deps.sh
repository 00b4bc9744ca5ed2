#!/usr/bin/env bash
# Installs otmpm's build, test and plotting dependencies from Debian packages
# (with pybind11, the Python headers and pytest for the Python package; venv,
# pip, setuptools and wheel for `pip install .`; nbclient and ipykernel to
# execute the notebooks headless; ccache, which CI uses to compile the pip
# build's files once).
# Idempotent: safe to run again; does nothing when everything is present.
# With arguments, installs those packages instead (scripts/fuzz.sh: clang).
#
# Both HDF5 flavours are installed side by side: the serial libhdf5-dev (a
# build with -DOTMPM_MPI=OFF) and, for distributed runs, OpenMPI with the
# parallel libhdf5-openmpi-dev. They do not conflict (headers and libraries
# in /usr/include/hdf5/{serial,openmpi}, /usr/lib/*/hdf5/{serial,openmpi});
# CMake finds the serial one through h5cc and the parallel one through h5pcc
# (HDF5_PREFER_PARALLEL, set when OTMPM_MPI is on). Installing the parallel
# flavour makes it the default of pkg-config's hdf5.pc (an alternative),
# which otmpm does not use.
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
  libopenmpi-dev openmpi-bin libhdf5-openmpi-dev
  libtomlplusplus-dev doctest-dev libcli11-dev doxygen
  python3 python3-matplotlib python3-h5py python3-numpy python3-meshio
  python3-dev pybind11-dev python3-pytest
  python3-venv python3-pip python3-setuptools python3-wheel
  python3-nbclient python3-nbformat python3-ipykernel
  ccache
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
