#!/usr/bin/env bash
# README command 2: install what is missing, build, run every test: C++ unit
# tests (CTest), the Python bridge tests (pytest) and the headless Blender
# tests, then the C++ unit tests again under AddressSanitizer + UBSan, then
# 45 s of libFuzzer on the C API (scripts/fuzz.sh, clang, build-fuzz/).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install_deps.sh
scripts/build.sh
(cd build && ctest --output-on-failure -j1)

cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPHOTONLM_SANITIZE=ON \
      -DPHOTONLM_BENCH=OFF -DPHOTONLM_PYTHON_TESTS=OFF > /dev/null
cmake --build build-asan -j"$(nproc)" --target photonlm_tests
(cd build-asan && ctest --output-on-failure -j1)

scripts/fuzz.sh 45
