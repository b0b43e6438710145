#!/usr/bin/env bash
# README command 2: set up (with the C++ tests enabled), fetch the real test data from
# Debian packages, then run the C++ tests (ctest) and the Python tests (pytest).
set -euo pipefail
cd "$(dirname "$0")/.."
# The main build leaves CUDA out (the default CPU-only library, and the NotBuiltError path);
# the light build below compiles the CUDA backend.
echo "[test $(date +%T)] set-up: the package with its C++ tests (scripts/setup.sh)"
bash scripts/setup.sh -Ccmake.define.SCANALIGN_BUILD_TESTS=ON -Ccmake.define.SCANALIGN_WITH_CUDA=OFF
echo "[test $(date +%T)] test-only and optional Python packages (evo: reference ATE/RPE; clifford: reference CGA; hypothesis and atheris: fuzzing; OpenCV: hand-eye reference; Ray and pyarrow: batch runs; yourdfpy, pin, example-robot-data: URDF robots and their FK oracle; rosbags: bags; rerun-sdk: viewer; Open3D, trimesh: interop; import-linter: the package's layers contract)"
.venv/bin/python -m pip install -q "evo>=1.20" "clifford>=1.4" "eaik>=1.2" "ur-analytic-ik>=0.1" "hypothesis>=6.100" \
  "atheris>=2.3" "opencv-python-headless>=4.8,<5" "ray>=2.9" "pyarrow>=12" "yourdfpy>=0.0.60" "pin>=4.1" \
  "example-robot-data>=6.0" "rosbags>=0.10" "rerun-sdk>=0.41" "trimesh>=4" "open3d>=0.18" "import-linter>=2.1"
echo "[test $(date +%T)] the package's layers (pyproject.toml [tool.importlinter], docs/architecture.md)"
.venv/bin/lint-imports --config pyproject.toml
echo "[test $(date +%T)] fetching test data (Debian packages libcgal-demo and python3-pcl)"
.venv/bin/python -m scanalign.data fetch
echo "[test $(date +%T)] ctest"
.venv/bin/ctest --test-dir build/py --output-on-failure -j2
echo "[test $(date +%T)] the light build (SCANALIGN_WITH_PCL=OFF, SCANALIGN_WITH_CUDA=ON: the GPU machine's configuration, scripts/gpu_check.sh; build folder build/light): Python module, build-info and backend tests"
PY=$(pwd)/.venv/bin/python
.venv/bin/cmake -S . -B build/light -G Ninja -DCMAKE_MAKE_PROGRAM="$(pwd)/.venv/bin/ninja" -DCMAKE_BUILD_TYPE=Release \
  -DSCANALIGN_WITH_PCL=OFF -DSCANALIGN_WITH_CUDA=ON -DSCANALIGN_BUILD_PYTHON=ON -DSCANALIGN_BUILD_TESTS=ON -DPython_EXECUTABLE="$PY" \
  -Dpybind11_DIR="$("$PY" -m pybind11 --cmakedir)" > build-light.log 2>&1 || { tail -n 40 build-light.log; exit 1; }
.venv/bin/cmake --build build/light -j2 --target _core scanalign_build_info_test scanalign_backend_test \
  >> build-light.log 2>&1 || { tail -n 60 build-light.log; exit 1; }
build/light/cpp/tests/scanalign_build_info_test
build/light/cpp/tests/scanalign_backend_test
echo "[test $(date +%T)] pytest"
SCANALIGN_REQUIRE_DATA=1 SCANALIGN_LIGHT_BUILD="$(pwd)/build/light" .venv/bin/python -m pytest -q tests
