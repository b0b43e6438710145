#!/usr/bin/env bash
# README command 2: set up (with the C++ tests enabled), fetch the real test data from
# Debian packages, then run the C++ tests (ctest) and the Python tests (pytest).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh -Ccmake.define.SCANALIGN_BUILD_TESTS=ON
echo "[test] test-only Python packages (evo: reference ATE/RPE; clifford: reference CGA; hypothesis and atheris: fuzzing; OpenCV: hand-eye reference; Ray and pyarrow: batch runs)"
.venv/bin/python -m pip install -q "evo>=1.20" "clifford>=1.4" "eaik>=1.2" "ur-analytic-ik>=0.1" "hypothesis>=6.100" "atheris>=2.3" "opencv-python-headless>=4.8,<5" "ray>=2.9" "pyarrow>=12"
echo "[test] fetching test data (Debian packages libcgal-demo and python3-pcl)"
.venv/bin/python -m scanalign.datasets fetch
echo "[test] ctest"
.venv/bin/ctest --test-dir build/py --output-on-failure -j2
echo "[test] pytest"
SCANALIGN_REQUIRE_DATA=1 .venv/bin/python -m pytest -q tests
