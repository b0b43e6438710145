#!/usr/bin/env bash
# Verifies the CUDA ICP backend on a machine with an NVIDIA GPU (issue 29), writing what it
# measured to OUTDIR. The machine needs nvcc, CMake, ninja, a C++ compiler and Python with
# numpy, pybind11 and pytest; no network, no PCL, no Eigen or GoogleTest package: those
# headers (and GoogleTest's static libraries) come along in .gpu-deps/, which
#     bash scripts/gpu_check.sh --prepare
# fills on the development machine (git ignores it; about 12 MB, with small_gicp's wheel for the
# benchmark's CPU peer).
#
#     bash scripts/gpu_check.sh OUTDIR      # about 5 minutes on 16 cores
#
# It builds the PCL-free configuration with CUDA (build/gpu), runs the backend's C++ tests
# (CPU against CUDA), the Python tests of both backends, and bench/bench_gpu.py; OUTDIR gets
# gpu.txt, build.log, backend_test.xml, pytest.xml, bench_gpu.json and bench_gpu.md.
set -euo pipefail
cd "$(dirname "$0")/.."
DEPS=.gpu-deps

if [[ "${1:-}" == "--prepare" ]]; then
  rm -rf "$DEPS" && mkdir -p "$DEPS/eigen/include" "$DEPS/eigen/share/eigen3" "$DEPS/gtest/include" "$DEPS/gtest/lib"
  cp -r /usr/include/eigen3 "$DEPS/eigen/include/"
  cp -r /usr/share/eigen3/cmake "$DEPS/eigen/share/eigen3/"
  cp -r /usr/include/gtest "$DEPS/gtest/include/"
  cp /usr/lib/x86_64-linux-gnu/libgtest.a /usr/lib/x86_64-linux-gnu/libgtest_main.a "$DEPS/gtest/lib/"
  # small_gicp, the CPU peer of bench/bench_gpu.py, as a wheel for the GPU machine's Python 3.12.
  python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
    --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 \
    -d "$DEPS/wheels" small-gicp || echo "small_gicp wheel not downloaded: bench_gpu.py will skip its rows"
  du -sh "$DEPS"
  exit 0
fi

OUT=${1:?usage: scripts/gpu_check.sh OUTDIR  (or --prepare on the development machine)}
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
PY=${PYTHON:-python3}
JOBS=$(nproc)
[[ -d "$DEPS/eigen" ]] || { echo "no $DEPS/eigen: run 'bash scripts/gpu_check.sh --prepare' where Eigen is installed"; exit 2; }
nvidia-smi -L | tee "$OUT/gpu.txt" || echo "nvidia-smi failed" | tee "$OUT/gpu.txt"

echo "[gpu] configure and build (PCL off, CUDA on, tests on) in build/gpu"
start=$(date +%s)
cmake -S . -B build/gpu -G Ninja -DCMAKE_BUILD_TYPE=Release -DSCANALIGN_WITH_PCL=OFF -DSCANALIGN_WITH_CUDA=ON \
  -DCMAKE_CUDA_ARCHITECTURES=native -DSCANALIGN_BUILD_PYTHON=ON -DSCANALIGN_BUILD_TESTS=ON \
  -DEigen3_DIR="$PWD/$DEPS/eigen/share/eigen3/cmake" -DGTEST_ROOT="$PWD/$DEPS/gtest" \
  -DPython_EXECUTABLE="$(command -v "$PY")" -Dpybind11_DIR="$("$PY" -m pybind11 --cmakedir)" > "$OUT/build.log" 2>&1 \
  || { tail -n 40 "$OUT/build.log"; exit 1; }
cmake --build build/gpu -j"$JOBS" --target _core scanalign_backend_test >> "$OUT/build.log" 2>&1 \
  || { tail -n 60 "$OUT/build.log"; exit 1; }
echo "[gpu] built in $(( $(date +%s) - start )) s"

echo "[gpu] C++: the CUDA engine against the CPU engine"
build/gpu/cpp/tests/scanalign_backend_test --gtest_output="xml:$OUT/backend_test.xml" || status=1

# The package's Python files with the CUDA module beside them.
PKG=$(mktemp -d)
mkdir "$PKG/scanalign"
for f in python/scanalign/*; do ln -s "$PWD/$f" "$PKG/scanalign/"; done
ln -s "$PWD"/build/gpu/_core*.so "$PKG/scanalign/"
export PYTHONPATH="$PKG"
if compgen -G "$DEPS/wheels/*.whl" > /dev/null; then
  "$PY" -m pip install -q --no-index --no-deps --no-compile --target "$PKG/site" "$DEPS"/wheels/*.whl \
    && export PYTHONPATH="$PKG:$PKG/site"
fi
"$PY" -c "from scanalign import registration; print('devices:', registration.cuda_devices())"

echo "[gpu] Python: both backends"
"$PY" -m pytest -q -p no:cacheprovider tests/test_cuda_backend.py --junitxml="$OUT/pytest.xml" || status=1

echo "[gpu] benchmark: CUDA against the CPU engine on all cores"
PYTHONUNBUFFERED=1 "$PY" bench/bench_gpu.py --out "$OUT" || status=1
exit "${status:-0}"
