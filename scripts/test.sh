#!/usr/bin/env bash
# README command 2: install what is missing, build, run every test: C++ unit
# tests (CTest), the Python bridge tests (pytest) and the headless Blender
# tests in Blender 3.4, 4.3 and 5.2 (blend_tests/blenders.txt says which where), the web
# viewer in headless Chromium against Blender 5.2 (web/test/test_web_viewer.py),
# then the C++ unit tests again under AddressSanitizer + UBSan, then
# 150,000 libFuzzer inputs from a fixed seed per fuzzer (100,000 on the C API, whose inputs bake
# scenes, 15,000 on part files; scripts/fuzz.sh, clang, build-fuzz/),
# tame floats (within +-1e8, no denormals): a regression run over the committed corpus (which
# holds every crash found so far) that does not fail on luck. Exploration with the full float
# range is scripts/fuzz.sh SECONDS (docs/robustness.md).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install_deps.sh
# The Debian roots of Blender 4.3 and 5.2 (scripts/blender_root.sh: made once, then cached) are made
# while the engine builds; a root that fails here is tried again by its tests, which then fail with
# the reason.
mkdir -p build
scripts/blender_root.sh trixie > build/root-trixie.log 2>&1 & trixie=$!
scripts/blender_root.sh sid > build/root-sid.log 2>&1 & sid=$!
scripts/build.sh
# The web viewer's page (web/dist) for its test: the locked three.js and esbuild from npm, then the bundle.
(cd web && npm ci --no-audit --no-fund && npm run build)
wait $trixie || true
wait $sid || true
cat build/root-trixie.log build/root-sid.log
(cd build && ctest --output-on-failure -j1)

cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPHOTONLM_SANITIZE=ON \
      -DPHOTONLM_BENCH=OFF -DPHOTONLM_PYTHON_TESTS=OFF > /dev/null
cmake --build build-asan -j"$(nproc)" --target photonlm_tests
(cd build-asan && ctest --output-on-failure -j1)

PHOTONLM_FUZZ_TAME=1 PHOTONLM_FUZZ_RUNS=150000 scripts/fuzz.sh
