#!/usr/bin/env bash
# Fuzzes the C API, the L-system reader, the JSON scene file reader and the
# part files of sharded bakes with
# libFuzzer + AddressSanitizer + UBSan (clang) for a bounded time:
# scripts/fuzz.sh [seconds per fuzzer, default 60].
# Builds in build-fuzz/ (separate from build/ and build-asan/; PHOTONLM_FUZZ_BUILD=DIR
# builds in DIR instead), runs each fuzzer over a working copy of its seed corpus (native/fuzz/corpus/<name>/,
# never modified here) and fails on any crash, leak, sanitizer report or hang
# (-timeout: one input may take at most 10 s). Crash inputs land in
# build-fuzz/artifacts/; reproduce one with build-fuzz/bin/<fuzzer> FILE.
set -euo pipefail
cd "$(dirname "$0")/.."
build="${PHOTONLM_FUZZ_BUILD:-build-fuzz}"
seconds="${1:-60}"
# PHOTONLM_FUZZ_RUNS=N: a fixed number of inputs from a fixed seed instead of a time limit, so
# that the run (and so the test command) is the same every time; fuzz_part_file, whose inputs
# may each merge a bake, runs a tenth of them.
command -v clang++ > /dev/null || scripts/install_deps.sh
export CC=clang CXX=clang++
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPHOTONLM_SANITIZE=ON -DPHOTONLM_FUZZ=ON \
      -DPHOTONLM_BENCH=OFF -DPHOTONLM_PYTHON_TESTS=OFF > /tmp/photonlm-fuzz-cmake.log 2>&1 || { cat /tmp/photonlm-fuzz-cmake.log; exit 1; }
rm -f /tmp/photonlm-fuzz-cmake.log
cmake --build "$build" -j"$(nproc)" --target fuzz_scene_api fuzz_lsystem fuzz_scene_file fuzz_part_file
# Debian's Embree, TBB and OpenEXR are not instrumented but run cleanly
# under ASan/LSan/UBSan here: no suppressions are needed (docs/robustness.md).
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1"
for fuzzer in scene_api lsystem scene_file part_file; do
  if [ -n "${PHOTONLM_FUZZ_RUNS:-}" ]; then
    runs="$PHOTONLM_FUZZ_RUNS"
    if [ "$fuzzer" = part_file ]; then runs=$((runs / 10)); fi
    if [ "$fuzzer" = scene_api ]; then runs=$((runs * 2 / 3)); fi  # each input bakes a scene: 20x the others' time
    limit=(-runs="$runs" -seed=1)
  else
    limit=(-max_total_time="$seconds")
  fi
  work="$build/corpus/$fuzzer"
  if [ -n "${PHOTONLM_FUZZ_RUNS:-}" ]; then  # a fixed run starts from the committed seeds only
    work="$build/corpus-fixed/$fuzzer"
    rm -rf "$work"
  fi
  mkdir -p "$work" "$build/artifacts"
  echo "fuzz.sh: fuzz_$fuzzer (${limit[*]})"
  log="$build/fuzz_$fuzzer.log"
  set +e
  "$build/bin/fuzz_$fuzzer" "${limit[@]}" -timeout=10 -rss_limit_mb=2048 -max_len=4096 \
    -print_final_stats=1 -artifact_prefix="$build/artifacts/" "$work" "native/fuzz/corpus/$fuzzer" > "$log" 2>&1
  status=$?
  set -e
  grep -vE '^#[0-9]+.*(NEW|REDUCE|pulse)|^INFO: ' "$log" | tail -60
  if [ "$status" -ne 0 ]; then
    echo "fuzz.sh: fuzz_$fuzzer FAILED (exit $status); inputs in $build/artifacts/"
    exit 1
  fi
done
echo "fuzz.sh: no crash, leak, sanitizer report or hang"
