#!/usr/bin/env bash
# Installs the dependencies, builds, and runs the whole test suite (the README's test command,
# run by .ci/run). Stages (README "Tests under sanitizers"), each timed on stderr:
#   1. release   the Release build (GCC, build/) and every test;
#   2. asan      the whole suite again under AddressSanitizer + UndefinedBehaviorSanitizer
#                (+ LeakSanitizer; clang, -O1, benchmarks off, build-asan/), the few heavy tests
#                on smaller inputs (tests/support/test_scale.hpp), with the libFuzzer harnesses
#                of tests/fuzz built in the same directory (libFuzzer's coverage instrumentation
#                on the readers only: cmake/NurbsregTarget.cmake, NURBSREG_FUZZ_MODULES);
#   3. fuzz      each harness for NURBSREG_FUZZ_SECONDS (default 30) from its seed corpus;
#   4. tsan      the parallel engine / ICP / registration / batch / service tests under
#                ThreadSanitizer (build-tsan/, only the binaries they need).
# NURBSREG_SANITIZERS=1 runs stages 2-4 too. Default 0 until the sanitizer stages have had a
# full verified run on CI hardware (issue 24: then CI, CI=true, is to run them always).
# NURBSREG_STAGES="asan tsan" (any of release asan fuzz tsan) runs only those, e.g. to repeat a
# failed stage. A failed stage does not stop the later ones (one CI run shows every stage's
# failures); the exit status is then 1 and the summary names the failed stages.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install_deps.sh

jobs="${NURBSREG_JOBS:-$(nproc)}"
sanitizers="${NURBSREG_SANITIZERS:-0}"
fuzz_seconds="${NURBSREG_FUZZ_SECONDS:-30}"
if [ "$sanitizers" = "0" ]; then
  stages="${NURBSREG_STAGES:-release}"
else
  stages="${NURBSREG_STAGES:-release asan fuzz tsan}"
fi
want() { [[ " $stages " == *" $1 "* ]]; }
timings=()
failed=()
stage_start=0
stage_cpu=0
# CPU seconds of this script's finished children (bash `times`, second line: user and system),
# beside the wall time: on a shared machine the wall time says little about the stage itself.
# `times` must run in this shell (a pipe or $(...) would report a fresh subshell's zeros).
cpu_file="$(mktemp)"
cpu_now=0
read_cpu() {
  times >"$cpu_file"
  cpu_now=$(sed -n 2p "$cpu_file" | awk '{ t = 0; for (i = 1; i <= 2; ++i) { split($i, a, /[ms]/); t += a[1] * 60 + a[2] } printf "%d", t }')
}
summary() {
  [ ${#timings[@]} -eq 0 ] || printf "== test.sh: %s\n" "${timings[@]}" >&2
  [ ${#failed[@]} -eq 0 ] || echo "== test.sh: FAILED stages: ${failed[*]}" >&2
  rm -f "$cpu_file"
}
trap summary EXIT
# run_stage NAME: times stage_NAME and records its failure. The stage functions check every
# command's status themselves (`|| return 1`): bash ignores `set -e` inside a function called
# from a `||` list.
run_stage() {
  want "$1" || return 0
  local start result=ok note=""
  start=$(date +%s)
  read_cpu
  local cpu0=$cpu_now
  echo "== test.sh: stage $1" >&2
  "stage_$1" || { result=FAILED; note=", FAILED"; failed+=("$1"); }
  read_cpu
  local wall=$(($(date +%s) - start)) cpu=$((cpu_now - cpu0))
  timings+=("$1 ${wall} s wall, ${cpu} s CPU, load average $(cut -d' ' -f1-3 /proc/loadavg)$note")
  echo "== test.sh: stage $1 took ${wall} s wall, ${cpu} s CPU ($result)" >&2
}

stage_release() {
  ./scripts/build.sh || return 1
  ctest --test-dir "${NURBSREG_BUILD_DIR:-build}" --output-on-failure --parallel "$(nproc)" \
    --timeout 600 || return 1
}

# Sanitizer builds: clang, -O1 with frame pointers (readable reports at a third of -O0's
# cost), assertions on, no benchmarks. Findings abort the test (-fno-sanitize-recover).
sanitizer_build() {  # dir sanitize extra-cmake-args... -- targets...
  local dir="$1" sanitize="$2"
  shift 2
  local args=()
  while [ "$1" != "--" ]; do args+=("$1"); shift; done
  shift
  CC=clang CXX=clang++ cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Debug \
    -DCMAKE_CXX_FLAGS_DEBUG="-O1 -g" -DCMAKE_C_FLAGS_DEBUG="-O1 -g" \
    -DNURBSREG_SANITIZE="$sanitize" -DNURBSREG_BUILD_BENCH=OFF -DNURBSREG_WERROR=OFF \
    "${args[@]}" >/dev/null || return 1
  cmake --build "$dir" --parallel "$jobs" ${1:+--target "$@"}
}
supp="$PWD/tests/sanitizers"

stage_asan() {
  sanitizer_build build-asan address,undefined -DNURBSREG_FUZZ=ON -- || return 1
  local status=0
  ASAN_OPTIONS="detect_leaks=1:suppressions=$supp/asan.supp:detect_stack_use_after_return=0" \
    LSAN_OPTIONS="suppressions=$supp/lsan.supp:print_suppressions=0" \
    UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:suppressions=$supp/ubsan.supp" \
    ctest --test-dir build-asan --output-on-failure --parallel "$(nproc)" --timeout 1200 \
    --output-junit "$PWD/build-asan/asan-tests.xml" || status=1
  ./scripts/slowest_tests.py build-asan/asan-tests.xml 15 build-asan >&2
  return $status
}

stage_fuzz() {
  sanitizer_build build-asan address,undefined -DNURBSREG_FUZZ=ON -- nurbsreg_fuzzers || return 1
  mkdir -p build-asan/fuzz-work
  local harness name work log status=0
  for harness in tests/fuzz/corpus/*/; do
    name="$(basename "$harness")"
    work="build-asan/fuzz-work/$name"
    log="build-asan/fuzz-work/$name.log"
    rm -rf "$work" && mkdir -p "$work"
    # New inputs go to the scratch directory (first), the committed seeds are only read.
    if ! LSAN_OPTIONS="suppressions=$supp/lsan.supp:print_suppressions=0" \
      ASAN_OPTIONS="detect_leaks=1:suppressions=$supp/asan.supp" \
      "build-asan/fuzz/$name" -max_total_time="$fuzz_seconds" -timeout=25 -rss_limit_mb=2048 \
      -print_final_stats=1 -artifact_prefix="build-asan/fuzz-work/$name-" "$work" "$harness" \
      >"$log" 2>&1; then
      tail -40 "$log" >&2
      echo "test.sh: fuzz harness $name found a failure (input saved as build-asan/fuzz-work/$name-*)" >&2
      timings+=("fuzz $name: FAILED")
      status=1
      continue
    fi
    local runs cov
    runs=$(grep -o 'stat::number_of_executed_units: [0-9]*' "$log" | grep -o '[0-9]*$')
    cov=$(grep -o 'cov: [0-9]* ft: [0-9]*' "$log" | tail -1)
    echo "== test.sh: fuzz $name: $runs runs in ${fuzz_seconds} s, $cov" >&2
    timings+=("fuzz $name: $runs runs, $cov")
  done
  return $status
}

stage_tsan() {
  # The tests that run work in parallel (TBB): thread-count invariance, parallel == serial, ICP
  # and global-alignment determinism, the batch pipeline (cli_tests drive the TSan-built binary)
  # and concurrent clients of `nurbsreg serve`. Only their binaries are built.
  sanitizer_build build-tsan thread -- engine_tests icp_tests registration_tests cli_tests \
    service_tests nurbsreg_cli || return 1
  TSAN_OPTIONS="suppressions=$supp/tsan.supp:halt_on_error=1:second_deadlock_stack=1" \
    ctest --test-dir build-tsan --output-on-failure --parallel "$(nproc)" --timeout 1200 \
    -R 'ThreadCount|Serial|Parallel|Determinis|Threads|Batch\.' || return 1
}

run_stage release
run_stage asan
run_stage fuzz
run_stage tsan
[ ${#failed[@]} -eq 0 ]
