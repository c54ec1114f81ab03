#!/usr/bin/env python3
"""Prints the slowest tests of a ctest JUnit file (ctest --output-junit) and, given the build
directory, each test program's total (python tests: the pytest file); given the CPU log of
tests/sanitizers/test_cpu.sh too, the slowest tests by CPU seconds and each program's CPU total.
scripts/test.sh shows them after the asan stage, whose test times decide whether CI stays
within its limit (on a shared machine the CPU seconds, not the wall times).
Usage: slowest_tests.py JUNIT_FILE [COUNT [BUILD_DIR [CPU_LOG]]]"""
import collections
import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET


def programs(build_dir):
    """Test name -> the program it runs (ctest's own listing of the tests' commands)."""
    try:
        listing = subprocess.run(["ctest", "--test-dir", build_dir, "--show-only=json-v1"],
                                 check=True, capture_output=True, text=True).stdout
    except (OSError, subprocess.CalledProcessError) as e:
        print(f"slowest_tests.py: cannot list the tests of {build_dir}: {e}", file=sys.stderr)
        return {}
    out = {}
    for test in json.loads(listing).get("tests", []):
        command = test.get("command") or ["?"]
        if os.path.basename(command[0]) == "test_cpu.sh" and len(command) > 1:
            command = command[1:]  # the sanitizer builds' launcher (tests/CMakeLists.txt)
        program = os.path.basename(command[0])
        if program.startswith("python"):
            program = os.path.basename(command[-1])
        out[test["name"]] = program
    return out


def cpu_seconds(log):
    """Test name -> CPU seconds (user + system) from test_cpu.sh's lines
    "user system wall command...": gtest programs run with --gtest_filter=NAME, pytest files as
    python.<file name>."""
    out = {}
    with open(log, encoding="utf-8", errors="replace") as f:
        for line in f:
            fields = line.split(maxsplit=3)
            if len(fields) < 4:
                continue
            try:
                cpu = float(fields[0]) + float(fields[1])
            except ValueError:
                continue
            name = None
            for arg in fields[3].split():
                if arg.startswith("--gtest_filter="):
                    name = arg[len("--gtest_filter="):]
                elif arg.endswith(".py") and os.path.basename(arg).startswith("test_"):
                    name = "python." + os.path.basename(arg)[:-3]
            if name is not None:
                out[name] = out.get(name, 0.0) + cpu
    return out


def main():
    if not 2 <= len(sys.argv) <= 5:
        sys.exit("usage: slowest_tests.py JUNIT_FILE [COUNT [BUILD_DIR [CPU_LOG]]]")
    count = int(sys.argv[2]) if len(sys.argv) >= 3 else 15
    try:
        root = ET.parse(sys.argv[1]).getroot()
    except (OSError, ET.ParseError) as e:
        sys.exit(f"slowest_tests.py: {sys.argv[1]}: {e}")
    cases = []
    for case in root.iter("testcase"):
        cases.append((float(case.get("time", "0")), case.get("name", "?"), case.get("status", "")))
    cases.sort(reverse=True)
    total = sum(c[0] for c in cases)
    print(f"== slowest {min(count, len(cases))} of {len(cases)} tests ({total:.0f} s in all):")
    for seconds, name, status in cases[:count]:
        note = "" if status in ("run", "") else f"  ({status})"
        print(f"   {seconds:8.1f} s  {name}{note}")
    if len(sys.argv) == 4:
        by_program = programs(sys.argv[3])
        totals = collections.Counter()
        counts = collections.Counter()
        for seconds, name, _ in cases:
            totals[by_program.get(name, "?")] += seconds
            counts[by_program.get(name, "?")] += 1
        print("== per test program:")
        for program, seconds in totals.most_common():
            print(f"   {seconds:8.1f} s  {program} ({counts[program]} tests)")
    if len(sys.argv) == 5:
        try:
            cpu = cpu_seconds(sys.argv[4])
        except OSError as e:
            sys.exit(f"slowest_tests.py: {sys.argv[4]}: {e}")
        ranked = sorted(cpu.items(), key=lambda item: item[1], reverse=True)
        print(f"== slowest {min(count, len(ranked))} of {len(ranked)} tests by CPU "
              f"({sum(cpu.values()):.0f} CPU s in all):")
        for name, seconds in ranked[:count]:
            print(f"   {seconds:8.1f} CPU s  {name}")
        by_program = programs(sys.argv[3])
        totals = collections.Counter()
        for name, seconds in ranked:
            totals[by_program.get(name, "?")] += seconds
        print("== CPU per test program:")
        for program, seconds in totals.most_common():
            print(f"   {seconds:8.1f} CPU s  {program}")


if __name__ == "__main__":
    main()
