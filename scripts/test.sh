#!/usr/bin/env bash
# Installs the dependencies, builds, and runs the whole test suite (the README's test command,
# run by .ci/run on every push). Stages (README "Tests under sanitizers"), each timed on stderr:
#   1. release   the Release build (GCC, build/) and every test;
#   2. fuzz      each harness for NURBSREG_FUZZ_SECONDS (default 30) from its seed corpus;
#   3. asan      the whole suite again under AddressSanitizer + UndefinedBehaviorSanitizer
#                (+ LeakSanitizer; clang, -O2, benchmarks off, build-asan/), the few heavy tests
#                on smaller inputs (tests/support/test_scale.hpp), with the libFuzzer harnesses
#                of tests/fuzz built in the same directory (libFuzzer's coverage instrumentation
#                on the readers only: cmake/NurbsregTarget.cmake, NURBSREG_FUZZ_MODULES);
#   4. tsan      the tests of our own threads (the service's admission and workers, concurrent
#                clients of `nurbsreg serve`) under ThreadSanitizer (build-tsan/, only the
#                binaries they need).
# Every stage runs by default; NURBSREG_SANITIZERS=0 runs the release stage only. NURBSREG_STAGES="asan tsan" (any of release asan fuzz tsan) runs only those,
# e.g. to repeat a failed stage. A failed stage does not stop the later ones (one CI run shows every
# stage's failures); the exit status is then 1 and the summary names the failed stages.
#
# Every stage has a wall-clock budget (seconds; NURBSREG_BUDGET_RELEASE, _ASAN, _FUZZ, _TSAN;
# 0 = none). A stage still running at its budget is killed and FAILS, naming the stage and the
# budget: CI stops at 90 minutes, and a run that silently grew past it would end with no result
# at all. The defaults are the measured cold times on a fresh 2-core machine with a margin
# (README). A sanitizer stage whose budget no longer fits in CI's time (NURBSREG_CI_SECONDS,
# 85 min from the start) is not started and is named NOT RUN: with a warm compiler cache (CI
# after a session's builds) all four fit; cold, the release and asan stages do.
set -euo pipefail
self="$(cd "$(dirname "$0")" && pwd)/$(basename "$0")"
cd "$(dirname "$0")/.."

# ccache (when present) rewrites this checkout's absolute paths as relative ones and leaves the
# working directory out of its hashes, so a clean clone elsewhere (CI's) reuses the objects
# another checkout of the same sources compiled on this machine.
export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1
jobs="${NURBSREG_JOBS:-$(nproc)}"
sanitizers="${NURBSREG_SANITIZERS:-1}"
fuzz_seconds="${NURBSREG_FUZZ_SECONDS:-30}"
if [ "$sanitizers" = "0" ]; then
  stages="${NURBSREG_STAGES:-release}"
else
  stages="${NURBSREG_STAGES:-release asan fuzz tsan}"
fi
want() { [[ " $stages " == *" $1 "* ]]; }
# The release stage alone (the default) has the whole of CI's time but the dependencies': its
# budget only bounds a hang. With the sanitizer stages it has its share of the estimate.
if [ "$sanitizers" = "0" ]; then
  budget_release="${NURBSREG_BUDGET_RELEASE:-4800}"
else
  budget_release="${NURBSREG_BUDGET_RELEASE:-1800}"
fi
budget_asan="${NURBSREG_BUDGET_ASAN:-4200}"
# CI's time for the whole script (dependencies included), with 5 minutes' margin on its 90; 0 =
# start every stage whatever the time.
ci_seconds="${NURBSREG_CI_SECONDS:-5100}"
script_start=$(date +%s)
not_run=()
budget_fuzz="${NURBSREG_BUDGET_FUZZ:-720}"
budget_tsan="${NURBSREG_BUDGET_TSAN:-2400}"
timings=()
failed=()
# CPU seconds of this script's finished children (bash `times`, second line: user and system),
# beside the wall time: on a shared machine the wall time says little about the stage itself.
# `times` must run in this shell (a pipe or $(...) would report a fresh subshell's zeros).
cpu_now=0
read_cpu() {
  times >"$cpu_file"
  cpu_now=$(sed -n 2p "$cpu_file" | awk '{ t = 0; for (i = 1; i <= 2; ++i) { split($i, a, /[ms]/); t += a[1] * 60 + a[2] } printf "%d", t }')
}
note() { [ -z "${NURBSREG_TEST_NOTES:-}" ] || echo "$*" >>"$NURBSREG_TEST_NOTES"; }
summary() {
  [ ${#timings[@]} -eq 0 ] || printf "== test.sh: %s\n" "${timings[@]}" >&2
  [ -s "$NURBSREG_TEST_NOTES" ] && sed 's/^/== test.sh: /' "$NURBSREG_TEST_NOTES" >&2
  [ ${#not_run[@]} -eq 0 ] || echo "== test.sh: NOT RUN for CI's time: ${not_run[*]} (see above)" >&2
  [ ${#failed[@]} -eq 0 ] || echo "== test.sh: FAILED stages: ${failed[*]}" >&2
  rm -f "$cpu_file" "$NURBSREG_TEST_NOTES"
}
# run_stage NAME: runs stage_NAME in a child process (this script with `--stage NAME`) under
# its budget, times it and records its failure. The stage functions check every command's
# status themselves (`|| return 1`): bash ignores `set -e` inside a function called from a `||`
# list.
run_stage() {
  want "$1" || return 0
  local start result=ok status=0 budget_var="budget_$1"
  local budget="${!budget_var}"
  start=$(date +%s)
  # A sanitizer stage starts only if its whole budget fits in what is left of CI's time: on a
  # machine whose compiler cache is cold (a fresh machine, no session built these trees) the
  # later stages cannot all fit in 90 minutes, and a run cut off at the limit has no result at
  # all. Such a stage is NOT RUN, named in the summary; the stages that ran still decide.
  local left=$((ci_seconds - (start - script_start)))
  if [ "$1" != release ] && [ "$ci_seconds" -gt 0 ] && [ "$budget" -gt 0 ] &&
    [ "$budget" -gt "$left" ]; then
    echo "== test.sh: stage $1 NOT RUN: its budget of ${budget} s does not fit in the ${left} s left of NURBSREG_CI_SECONDS=${ci_seconds} (a cold compiler cache?); run it alone with NURBSREG_STAGES=$1" >&2
    timings+=("$1 NOT RUN: budget ${budget} s > ${left} s left of CI's time")
    not_run+=("$1")
    return 0
  fi
  read_cpu
  local cpu0=$cpu_now
  echo "== test.sh: stage $1 (budget ${budget} s wall)" >&2
  if [ "$budget" -gt 0 ]; then
    # timeout runs the stage in a process group of its own and at the budget signals all of it
    # (ctest and the tests with it), 30 s later kills it. That group does not get a terminal's
    # Ctrl-C: this script forwards it (and a TERM) while it waits.
    timeout --kill-after=30 "$budget" "$self" --stage "$1" &
    local pid=$!
    trap 'kill -TERM "$pid" 2>/dev/null; interrupted=1' INT TERM
    wait "$pid" || status=$?
    while kill -0 "$pid" 2>/dev/null; do wait "$pid" || status=$?; done
    trap - INT TERM
  else
    "$self" --stage "$1" || status=$?
  fi
  read_cpu
  local wall=$(($(date +%s) - start)) cpu=$((cpu_now - cpu0))
  if [ "$status" -eq 124 ] || [ "$status" -eq 137 ]; then
    result="FAILED: stopped at its budget of ${budget} s wall (NURBSREG_BUDGET_${1^^}; CI's limit is 90 min)"
  elif [ "$status" -ne 0 ]; then
    result=FAILED
  fi
  [ "$status" -eq 0 ] || failed+=("$1")
  timings+=("$1 ${wall} s wall, ${cpu} s CPU, load average $(cut -d' ' -f1-3 /proc/loadavg) ($result)")
  echo "== test.sh: stage $1 took ${wall} s wall, ${cpu} s CPU ($result)" >&2
  [ "$interrupted" -eq 0 ] || exit 130
}
interrupted=0

stage_release() {
  ./scripts/build.sh || return 1
  ctest --test-dir "${NURBSREG_BUILD_DIR:-build}" --output-on-failure --parallel "$(nproc)" \
    --timeout 600 || return 1
}

# Sanitizer builds: clang, -O2 with frame pointers (cmake/NurbsregTarget.cmake) and line tables
# (reports name file:line; full debug info only lengthens compiles and links), assertions on, no
# benchmarks. -O2, not -O1: at -O1 Eigen's small fixed-size operations stay out-of-line calls,
# and the engine's tests spend their time in them (README "Tests under sanitizers" has the A/B).
# Findings abort the test (-fno-sanitize-recover).
sanitizer_flags="${NURBSREG_SANITIZER_FLAGS:--O2 -gline-tables-only}"
sanitizer_build() {  # dir sanitize extra-cmake-args... -- targets...
  local dir="$1" sanitize="$2"
  shift 2
  local args=()
  while [ "$1" != "--" ]; do args+=("$1"); shift; done
  shift
  CC=clang CXX=clang++ cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Debug \
    -DCMAKE_CXX_FLAGS_DEBUG="$sanitizer_flags" -DCMAKE_C_FLAGS_DEBUG="$sanitizer_flags" \
    -DNURBSREG_SANITIZE="$sanitize" -DNURBSREG_BUILD_BENCH=OFF -DNURBSREG_WERROR=OFF \
    "${args[@]}" >/dev/null || return 1
  cmake --build "$dir" --parallel "$jobs" ${1:+--target "$@"}
}
supp="$PWD/tests/sanitizers"

stage_asan() {
  sanitizer_build build-asan address,undefined -DNURBSREG_FUZZ=ON -- || return 1
  local status=0 cpu_log="$PWD/build-asan/asan-test-cpu.log"
  rm -f "$cpu_log"
  NURBSREG_TEST_CPU_LOG="$cpu_log" \
    ASAN_OPTIONS="detect_leaks=1:suppressions=$supp/asan.supp:detect_stack_use_after_return=0" \
    LSAN_OPTIONS="suppressions=$supp/lsan.supp:print_suppressions=0" \
    UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:suppressions=$supp/ubsan.supp" \
    ctest --test-dir build-asan --output-on-failure --parallel "$(nproc)" --timeout 1200 \
    --output-junit "$PWD/build-asan/asan-tests.xml" || status=1
  ./scripts/slowest_tests.py build-asan/asan-tests.xml 15 build-asan "$cpu_log" >&2
  return $status
}

# One harness for NURBSREG_FUZZ_SECONDS from its seed corpus; prints its executions and coverage.
fuzz_harness() {  # corpus-dir
  local name work log
  name="$(basename "$1")"
  work="build-asan/fuzz-work/$name"
  log="build-asan/fuzz-work/$name.log"
  rm -rf "$work" && mkdir -p "$work"
  # New inputs go to the scratch directory (first), the committed seeds are only read.
  if ! LSAN_OPTIONS="suppressions=$supp/lsan.supp:print_suppressions=0" \
    ASAN_OPTIONS="detect_leaks=1:suppressions=$supp/asan.supp" \
    "build-asan/fuzz/$name" -max_total_time="$fuzz_seconds" -timeout=25 -rss_limit_mb=2048 \
    -print_final_stats=1 -artifact_prefix="build-asan/fuzz-work/$name-" "$work" "$1" \
    >"$log" 2>&1; then
    # One write, so that a harness running beside it cannot split the report.
    { tail -40 "$log"; echo "test.sh: fuzz harness $name found a failure (input saved as build-asan/fuzz-work/$name-*)"; } | cat >&2
    note "fuzz $name: FAILED"
    return 1
  fi
  local runs cov
  runs=$(grep -o 'stat::number_of_executed_units: [0-9]*' "$log" | grep -o '[0-9]*$')
  cov=$(grep -o 'cov: [0-9]* ft: [0-9]*' "$log" | tail -1)
  echo "== test.sh: fuzz $name: $runs runs in ${fuzz_seconds} s, $cov" >&2
  note "fuzz $name: $runs runs in ${fuzz_seconds} s, $cov"
}

stage_fuzz() {
  sanitizer_build build-asan address,undefined -DNURBSREG_FUZZ=ON -- nurbsreg_fuzzers || return 1
  mkdir -p build-asan/fuzz-work
  # The harnesses are single-threaded: one per core at a time (a harness's time is its own
  # -max_total_time, so they finish in the order they started).
  local harness pid status=0 running=()
  for harness in tests/fuzz/corpus/*/; do
    fuzz_harness "$harness" &
    running+=($!)
    if [ ${#running[@]} -ge "$jobs" ]; then
      wait "${running[0]}" || status=1
      running=("${running[@]:1}")
    fi
  done
  for pid in "${running[@]}"; do
    wait "$pid" || status=1
  done
  return $status
}

stage_tsan() {
  # The tests of our own threads and of the TBB-parallel code: the service's admission and
  # workers, concurrent clients of `nurbsreg serve` (service_tests drive the TSan-built binary)
  # and its frame streams; and every test that runs the engine's projection, ICP, global
  # registration, sampling or the batch pipeline on more than one thread (the thread-count
  # invariance tests, `batch`). Debian's libtbb is not instrumented (TSan would not see its
  # scheduler's synchronisation and report every task's data), so this stage links a oneTBB built
  # here with -fsanitize=thread from Debian's source package of the same version
  # (scripts/tsan_tbb.sh; README "ThreadSanitizer and TBB").
  # Exported before the build too: it runs the test programs to list their tests (gtest discovery).
  export TSAN_OPTIONS="suppressions=$supp/tsan.supp:halt_on_error=1:second_deadlock_stack=1"
  local tbb_dir
  tbb_dir="$(./scripts/tsan_tbb.sh build-tsan/onetbb | tail -1)" || return 1
  # The instrumented library before Debian's for every program of the stage (the test programs'
  # own RUNPATH names it too; this also covers libraries such as OpenCASCADE's that load it).
  export LD_LIBRARY_PATH="${tbb_dir%/cmake/TBB}${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
  sanitizer_build build-tsan thread -DTBB_DIR="$tbb_dir" -- service_tests nurbsreg_cli \
    engine_tests icp_tests registration_tests cli_tests tsan_tbb_canary || return 1
  if ldd build-tsan/bin/nurbsreg | grep -q 'libtbb.so.* => /usr/'; then
    echo "test.sh: build-tsan/bin/nurbsreg loads Debian's uninstrumented libtbb" >&2
    return 1
  fi
  ctest --test-dir build-tsan --output-on-failure --parallel "$(nproc)" --timeout 1200 \
    -R "$tsan_tests" || return 1
}
# The tsan stage's tests (ctest -R): the service's, every test of more than one thread, and the
# canary that shows a race inside a TBB task is reported (tests/sanitizers/tsan_tbb_canary.cpp).
tsan_tests='^(Serve|ServeFrames|RequestOptions|RequestCorpus|Batch|TsanTbb)\.|Thread|Parallel|Serial|Concurrent'

if [ "${1:-}" = "--stage" ]; then
  # One stage, in the child process run_stage starts (its process group is the one a budget's
  # timeout stops).
  "stage_$2"
  exit
fi
cpu_file="$(mktemp)"
# Lines a stage adds to the summary (a stage runs in a child process, `--stage NAME`).
NURBSREG_TEST_NOTES="$(mktemp)"
export NURBSREG_TEST_NOTES
trap summary EXIT
deps_start=$(date +%s)
./scripts/install_deps.sh
timings+=("dependencies $(($(date +%s) - deps_start)) s wall")
# The fuzz stage before the asan suite: it is short and builds only the harnesses (in build-asan,
# the asan stage then builds the rest), so that a slow asan suite cannot leave CI without it.
run_stage release
run_stage fuzz
run_stage asan
run_stage tsan
[ ${#failed[@]} -eq 0 ]
