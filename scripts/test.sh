#!/usr/bin/env bash
# Installs the dependencies, builds, and runs the whole test suite (the README's test command,
# run by .ci/run). Stages (README "Tests under sanitizers"), each timed on stderr:
#   1. release   the Release build (GCC, build/) and every test;
#   2. asan      the whole suite again under AddressSanitizer + UndefinedBehaviorSanitizer
#                (clang, -O1, benchmarks off, build-asan/), with the libFuzzer harnesses of
#                tests/fuzz built in the same directory;
#   3. fuzz      each harness for NURBSREG_FUZZ_SECONDS (default 30) from its seed corpus;
#   4. tsan      the parallel engine / ICP / batch tests under ThreadSanitizer (build-tsan/).
# NURBSREG_SANITIZERS=1 runs stages 2-4 too. Default 0 until the sanitizer stages have had a
# full verified run on CI hardware (issue 24: then CI, CI=true, is to run them always).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install_deps.sh

jobs="${NURBSREG_JOBS:-$(nproc)}"
sanitizers="${NURBSREG_SANITIZERS:-0}"
fuzz_seconds="${NURBSREG_FUZZ_SECONDS:-30}"
timings=()
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
begin() { stage_start=$(date +%s); read_cpu; stage_cpu=$cpu_now; echo "== test.sh: stage $1" >&2; }
end() {
  read_cpu
  local wall=$(($(date +%s) - stage_start)) cpu=$((cpu_now - stage_cpu))
  timings+=("$1 ${wall} s wall, ${cpu} s CPU")
  echo "== test.sh: stage $1 took ${wall} s wall, ${cpu} s CPU" >&2
}
summary() {
  printf '== test.sh: %s\n' "${timings[@]}" >&2
  rm -f "$cpu_file"
}
trap summary EXIT

begin release
./scripts/build.sh
ctest --test-dir "${NURBSREG_BUILD_DIR:-build}" --output-on-failure --parallel "$(nproc)" \
  --timeout 600
end release

[ "$sanitizers" = "0" ] && exit 0

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
    "${args[@]}" >/dev/null
  cmake --build "$dir" --parallel "$jobs" ${1:+--target "$@"}
}
supp="$PWD/tests/sanitizers"

begin asan
sanitizer_build build-asan address,undefined -DNURBSREG_FUZZ=ON --
ASAN_OPTIONS="detect_leaks=1:suppressions=$supp/asan.supp:detect_stack_use_after_return=0" \
  LSAN_OPTIONS="suppressions=$supp/lsan.supp:print_suppressions=0" \
  UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:suppressions=$supp/ubsan.supp" \
  ctest --test-dir build-asan --output-on-failure --parallel "$(nproc)" --timeout 1200
end asan

begin fuzz
mkdir -p build-asan/fuzz-work
for harness in tests/fuzz/corpus/*/; do
  name="$(basename "$harness")"
  work="build-asan/fuzz-work/$name"
  rm -rf "$work" && mkdir -p "$work"
  # New inputs go to the scratch directory (first), the committed seeds are only read.
  LSAN_OPTIONS="suppressions=$supp/lsan.supp:print_suppressions=0" \
    ASAN_OPTIONS="detect_leaks=1:suppressions=$supp/asan.supp" \
    "build-asan/fuzz/$name" -max_total_time="$fuzz_seconds" -timeout=25 -rss_limit_mb=2048 \
    -print_final_stats=1 -artifact_prefix="build-asan/fuzz-work/$name-" "$work" "$harness" \
    >"build-asan/fuzz-work/$name.log" 2>&1 || {
      tail -40 "build-asan/fuzz-work/$name.log" >&2
      echo "test.sh: fuzz harness $name found a failure (input saved as build-asan/fuzz-work/$name-*)" >&2
      exit 1
    }
  runs=$(grep -o 'stat::number_of_executed_units: [0-9]*' "build-asan/fuzz-work/$name.log" | grep -o '[0-9]*$')
  cov=$(grep -o 'cov: [0-9]* ft: [0-9]*' "build-asan/fuzz-work/$name.log" | tail -1)
  echo "== test.sh: fuzz $name: $runs runs in ${fuzz_seconds} s, $cov" >&2
  timings+=("fuzz $name: $runs runs, $cov")
done
end fuzz

begin tsan
# The tests that run work in parallel (TBB): thread-count invariance, parallel == serial, ICP
# determinism, and the batch pipeline (cli_tests drive the TSan-built binary).
sanitizer_build build-tsan thread -- engine_tests icp_tests cli_tests nurbsreg_cli
TSAN_OPTIONS="suppressions=$supp/tsan.supp:halt_on_error=1:second_deadlock_stack=1" \
  ctest --test-dir build-tsan --output-on-failure --parallel "$(nproc)" --timeout 1200 \
  -R 'ThreadCount|Serial|Parallel|Determinis|Threads|Batch\.'
end tsan
