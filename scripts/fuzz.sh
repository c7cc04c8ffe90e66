#!/usr/bin/env bash
# Fuzzes the C API, the L-system reader and the JSON scene file reader with
# libFuzzer + AddressSanitizer + UBSan (clang) for a bounded time:
# scripts/fuzz.sh [seconds per fuzzer, default 60].
# Builds in build-fuzz/ (separate from build/ and build-asan/), runs each
# fuzzer over a working copy of its seed corpus (native/fuzz/corpus/<name>/,
# never modified here) and fails on any crash, leak, sanitizer report or hang
# (-timeout: one input may take at most 10 s). Crash inputs land in
# build-fuzz/artifacts/; reproduce one with build-fuzz/bin/<fuzzer> FILE.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
# PHOTONLM_FUZZ_RUNS=N: a fixed number of inputs from a fixed seed instead of a time limit, so
# that the run (and so the test command) is the same every time.
if [ -n "${PHOTONLM_FUZZ_RUNS:-}" ]; then
  limit=(-runs="$PHOTONLM_FUZZ_RUNS" -seed=1)
else
  limit=(-max_total_time="$seconds")
fi
command -v clang++ > /dev/null || scripts/install_deps.sh
export CC=clang CXX=clang++
cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPHOTONLM_SANITIZE=ON -DPHOTONLM_FUZZ=ON \
      -DPHOTONLM_BENCH=OFF -DPHOTONLM_PYTHON_TESTS=OFF > /tmp/photonlm-fuzz-cmake.log 2>&1 || { cat /tmp/photonlm-fuzz-cmake.log; exit 1; }
rm -f /tmp/photonlm-fuzz-cmake.log
cmake --build build-fuzz -j"$(nproc)" --target fuzz_scene_api fuzz_lsystem fuzz_scene_file
# Debian's Embree, TBB and OpenEXR are not instrumented but run cleanly
# under ASan/LSan/UBSan here: no suppressions are needed (docs/robustness.md).
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1"
for fuzzer in scene_api lsystem scene_file; do
  work="build-fuzz/corpus/$fuzzer"
  if [ -n "${PHOTONLM_FUZZ_RUNS:-}" ]; then  # a fixed run starts from the committed seeds only
    work="build-fuzz/corpus-fixed/$fuzzer"
    rm -rf "$work"
  fi
  mkdir -p "$work" build-fuzz/artifacts
  echo "fuzz.sh: fuzz_$fuzzer (${limit[*]})"
  log="build-fuzz/fuzz_$fuzzer.log"
  set +e
  build-fuzz/bin/fuzz_"$fuzzer" "${limit[@]}" -timeout=10 -rss_limit_mb=2048 -max_len=4096 \
    -print_final_stats=1 -artifact_prefix=build-fuzz/artifacts/ "$work" "native/fuzz/corpus/$fuzzer" > "$log" 2>&1
  status=$?
  set -e
  grep -vE '^#[0-9]+.*(NEW|REDUCE|pulse)|^INFO: ' "$log" | tail -60
  if [ "$status" -ne 0 ]; then
    echo "fuzz.sh: fuzz_$fuzzer FAILED (exit $status); inputs in build-fuzz/artifacts/"
    exit 1
  fi
done
echo "fuzz.sh: no crash, leak, sanitizer report or hang"
