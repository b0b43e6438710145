#!/usr/bin/env bash
# Builds the C++ library and its GoogleTest suite with AddressSanitizer and
# UndefinedBehaviorSanitizer (no Python module) in build/sanitize, and runs the tests: any
# invalid memory access, leak-free-use, overflow or undefined behaviour fails the run.
# Needs what scripts/setup.sh installs (compiler, Eigen, PCL, GoogleTest). About 15 minutes
# on 2 cores, most of it compiling the PCL translation units.
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B build/sanitize -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSCANALIGN_SANITIZE=ON \
  -DSCANALIGN_BUILD_PYTHON=OFF -DSCANALIGN_BUILD_TESTS=ON
cmake --build build/sanitize -j "${CMAKE_BUILD_PARALLEL_LEVEL:-2}" --target scanalign_unit_tests
# Leak checking is off: the OpenMP runtime keeps its thread pool until exit, which LSan reports.
ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  build/sanitize/cpp/tests/scanalign_unit_tests --gtest_brief=1
