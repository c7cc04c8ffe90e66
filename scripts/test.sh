#!/usr/bin/env bash
# README command 2: install what is missing, build, run every test: C++ unit
# tests (CTest), the Python bridge tests (pytest) and the headless Blender
# tests, then the C++ unit tests again under AddressSanitizer + UBSan, then
# 150,000 libFuzzer inputs from a fixed seed on the C API (scripts/fuzz.sh, clang, build-fuzz/),
# tame floats (within +-1e8, no denormals): a regression run over the committed corpus (which
# holds every crash found so far) that does not fail on luck. Exploration with the full float
# range is scripts/fuzz.sh SECONDS (docs/robustness.md).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install_deps.sh
scripts/build.sh
(cd build && ctest --output-on-failure -j1)

cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPHOTONLM_SANITIZE=ON \
      -DPHOTONLM_BENCH=OFF -DPHOTONLM_PYTHON_TESTS=OFF > /dev/null
cmake --build build-asan -j"$(nproc)" --target photonlm_tests
(cd build-asan && ctest --output-on-failure -j1)

PHOTONLM_FUZZ_TAME=1 PHOTONLM_FUZZ_RUNS=150000 scripts/fuzz.sh
