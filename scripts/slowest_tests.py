#!/usr/bin/env python3
"""Prints the slowest tests of a ctest JUnit file (ctest --output-junit). scripts/test.sh shows
them after the asan stage, whose test times decide whether CI stays within its limit.
Usage: slowest_tests.py FILE [COUNT]"""
import sys
import xml.etree.ElementTree as ET


def main():
    if len(sys.argv) not in (2, 3):
        sys.exit("usage: slowest_tests.py JUNIT_FILE [COUNT]")
    count = int(sys.argv[2]) if len(sys.argv) == 3 else 15
    try:
        root = ET.parse(sys.argv[1]).getroot()
    except (OSError, ET.ParseError) as e:
        sys.exit(f"slowest_tests.py: {sys.argv[1]}: {e}")
    cases = []
    for case in root.iter("testcase"):
        name = case.get("name", "?")
        seconds = float(case.get("time", "0"))
        status = case.get("status", "")
        cases.append((seconds, name, status))
    cases.sort(reverse=True)
    total = sum(c[0] for c in cases)
    print(f"== slowest {min(count, len(cases))} of {len(cases)} tests ({total:.0f} s in all):")
    for seconds, name, status in cases[:count]:
        print(f"   {seconds:8.1f} s  {name}{'' if status in ('run', '') else '  (' + status + ')'}")


if __name__ == "__main__":
    main()
