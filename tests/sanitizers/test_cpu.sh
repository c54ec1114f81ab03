#!/usr/bin/env bash
# Runs one test program (the sanitizer builds' test launcher, tests/CMakeLists.txt) and, when
# NURBSREG_TEST_CPU_LOG names a file, appends a line "user-s system-s wall-s command..." to it:
# the test's CPU seconds with those of every process it waited for (the CLI tests' `nurbsreg`
# runs). scripts/test.sh's asan stage sets it; scripts/slowest_tests.py lists the slowest tests
# by CPU, which on a shared machine say more than ctest's wall times.
if [ -z "${NURBSREG_TEST_CPU_LOG:-}" ]; then
  exec "$@"
fi
args="$*"
TIMEFORMAT="%3U %3S %3R ${args//%/%%}"
exec 3>&2
{ time "$@" 2>&3 3>&-; } 2>>"$NURBSREG_TEST_CPU_LOG"
