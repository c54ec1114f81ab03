"""Shared fixtures of the Python package's tests: the `nurbsreg` binary to compare with (ctest
sets NURBSREG_BINARY, NURBSREG_EXAMPLES_DIR and PYTHONPATH; see tests/CMakeLists.txt)."""

import csv
import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
EXAMPLES = pathlib.Path(os.environ.get("NURBSREG_EXAMPLES_DIR", ROOT / "examples"))
BINARY = pathlib.Path(os.environ.get("NURBSREG_BINARY", ROOT / "build" / "bin" / "nurbsreg"))
PANEL = EXAMPLES / "panel.json"
SHARED = pathlib.Path(os.environ.get("NURBSREG_SHARED_DIR", ROOT.parent / "shared"))
# Sanitizer builds (tests/CMakeLists.txt sets it; C++: tests/support/test_scale.hpp): the few
# heavy tests run on smaller inputs, and time bounds allow for the instrumented code's slowness.
REDUCED = os.environ.get("NURBSREG_REDUCED_TESTS") == "1"


def sized(full, reduced):
    """`full` in the Release suite, `reduced` under sanitizers."""
    return reduced if REDUCED else full


PANEL_SCAN_POINTS = sized(20000, 5000)


def without_times(report):
    """A report (alignment or inspect.json) without its timings, the only fields two runs may
    differ in: every "seconds" and "*_seconds" field, at any depth, but the time limit asked
    for."""
    def strip(value):
        if isinstance(value, dict):
            return {k: strip(v) for k, v in value.items()
                    if not (k == "seconds" or (k.endswith("_seconds") and k != "time_limit_seconds"))}
        if isinstance(value, list):
            return [strip(v) for v in value]
        return value
    return strip(json.loads(json.dumps(report)))


# Under AddressSanitizer ctest preloads the ASan runtime into the interpreter (not instrumented;
# tests/CMakeLists.txt). The binary links its own copy, and a process with both aborts at start
# ("incompatible ASan runtimes"): the binary runs without the preload.
CLI_ENV = {k: v for k, v in os.environ.items() if k != "LD_PRELOAD"}


def run_cli(*args, check=True):
    """Runs the CLI; returns the CompletedProcess (text)."""
    done = subprocess.run([str(BINARY), *map(str, args)], capture_output=True, text=True,
                          env=CLI_ENV)
    if check and done.returncode != 0:
        raise AssertionError(f"nurbsreg {' '.join(map(str, args))} exited {done.returncode}:\n"
                             f"{done.stderr}")
    return done


def read_csv_columns(path):
    """A CSV table with a header line as {name: float64 array}; the CLI prints shortest
    round-trip numbers, so float() gives back the exact doubles."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    return {name: np.array([float(r[k]) for r in body]) for k, name in enumerate(header)}


def read_pose_file(path):
    return np.array([[float(x) for x in line.split()] for line in open(path) if line.strip()])


@pytest.fixture(scope="session")
def panel():
    import nurbsreg
    return nurbsreg.load_model(PANEL)


@pytest.fixture(scope="session")
def panel_scan(tmp_path_factory):
    """A 20,000-point noisy scan of the panel written by the CLI (float32 PCD), moved by a few
    degrees and millimetres, with its true pose (5,000 points under sanitizers: every test
    that aligns it runs the global stage and the exact ICP on all of its points)."""
    d = tmp_path_factory.mktemp("scan")
    scan, pose = d / "scan.pcd", d / "true_pose.txt"
    run_cli("synth", "--model", PANEL, "--points", PANEL_SCAN_POINTS, "--noise", 0.02,
            "--seed", 3, "--pose", "2 -1 3 2 -1 1", "--out", scan, "--out-pose", pose)
    return scan, read_pose_file(pose)
