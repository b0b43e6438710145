#!/usr/bin/env bash
# Sets up scanalign on a fresh Debian (bookworm) machine, as root:
#  - system packages from Debian: the compiler, PCL 1.13, Eigen 3.4, FLANN, GoogleTest;
#  - a virtual environment .venv with the build tools from PyPI;
#  - builds and installs the package (C++ core + Python module) into .venv.
# Extra arguments are passed to the CMake configure step (e.g. -Ccmake.define.X=Y).
set -euo pipefail
cd "$(dirname "$0")/.."

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
PKGS=(build-essential pkg-config libpcl-dev libeigen3-dev libflann-dev libgtest-dev)
missing=()
for p in "${PKGS[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
if ! command -v python3 >/dev/null; then missing+=(python3 python3-dev python3-venv); fi
if [ "${#missing[@]}" -gt 0 ]; then
  echo "[setup] installing Debian packages: ${missing[*]}"
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

if [ ! -x .venv/bin/python ]; then
  echo "[setup] creating .venv"
  python3 -m venv .venv || {
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends python3-venv python3-dev
    python3 -m venv .venv
  }
fi
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q "scikit-build-core>=0.10" "pybind11>=2.12" "cmake>=3.20" ninja numpy pytest scipy \
  matplotlib Pillow tqdm PyYAML plyfile "pybind11-stubgen>=2.5"

echo "[setup] building and installing scanalign (build folder build/py)"
# -j2: the build machine has 2 cores and PCL translation units are memory-hungry.
CMAKE_BUILD_PARALLEL_LEVEL="${CMAKE_BUILD_PARALLEL_LEVEL:-2}" \
  .venv/bin/python -m pip install -q --no-build-isolation -Cbuild-dir=build/py "$@" .
echo "[setup] done: $(.venv/bin/python -c 'import scanalign; print("scanalign", scanalign.__version__)')"
