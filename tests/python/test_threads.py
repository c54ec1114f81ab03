"""Threads and Ctrl-C: two Python threads project at once (the GIL is released) with the
answers of one after the other; Ctrl-C stops a long call."""

import os
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np

import nurbsreg
from conftest import PANEL, sized

# Under sanitizers (conftest.REDUCED) the work is ~10x slower: a tenth of the points keeps the
# calls long enough for the signal to land inside them, and the latency bound and time-out grow
# with the slower code between two cancellation checks.
LATENCY = sized(5.0, 20.0)
TIMEOUT = sized(120, 600)


def test_two_threads_at_once_give_the_serial_answers(panel):
    rng = np.random.default_rng(1)
    frames = [rng.uniform([0, 0, -5], [100, 100, 20], (60000, 3)) for _ in range(2)]
    serial = [nurbsreg.project(panel, f) for f in frames]
    results = [None, None]

    def run(k):
        results[k] = nurbsreg.project(panel, frames[k])

    threads = [threading.Thread(target=run, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for mine, reference in zip(results, serial):
        np.testing.assert_array_equal(mine.foot, reference.foot)
        np.testing.assert_array_equal(mine.distance, reference.distance)
        np.testing.assert_array_equal(mine.entity, reference.entity)


def test_python_runs_while_a_projection_runs(panel):
    # With the GIL held for the call, this thread would stand still until it returned: its
    # longest pause between two loop turns would be about the call's duration.
    points = np.random.default_rng(2).uniform([0, 0, -5], [100, 100, 20],
                                              (sized(200000, 50000), 3))
    worker = threading.Thread(target=nurbsreg.project, args=(panel, points),
                              kwargs={"threads": 1})
    start = time.perf_counter()
    worker.start()
    last, longest = time.perf_counter(), 0.0
    while worker.is_alive():
        now = time.perf_counter()
        longest = max(longest, now - last)
        last = now
    duration = time.perf_counter() - start
    assert longest < 0.5 * duration, (longest, duration)


def test_two_aligners_in_two_threads(panel):
    scans = [nurbsreg.synth(panel, 5000, noise=0.01, pose=(1, 2, 1, 1, 0, 0), seed=s).points
             for s in (1, 2)]
    serial = [nurbsreg.align(panel, s).T_model_scan for s in scans]
    poses = [None, None]

    def run(k):
        poses[k] = nurbsreg.Aligner(panel).align(scans[k]).T_model_scan

    threads = [threading.Thread(target=run, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for mine, reference in zip(poses, serial):
        np.testing.assert_array_equal(mine, reference)


def test_ctrl_c_stops_a_long_projection():
    # In a child process: SIGINT to itself 0.2 s into a projection of 3 M points spread through
    # the model's box (over 10 s of work on two cores); the call must end with KeyboardInterrupt
    # long before it would finish (within about half a second of the signal when idle).
    script = textwrap.dedent(f"""
        import os, signal, threading, time
        import numpy as np, nurbsreg
        model = nurbsreg.load_model({str(PANEL)!r})
        points = np.random.default_rng(0).uniform([0, 0, -5], [100, 100, 20],
                                                  ({sized(3_000_000, 300_000)}, 3))
        nurbsreg.project(model, points[:1000])
        t0 = time.perf_counter()
        threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGINT)).start()
        try:
            nurbsreg.project(model, points)
            print("finished", time.perf_counter() - t0)
        except KeyboardInterrupt:
            print("interrupted", time.perf_counter() - t0)
        # The model is still usable afterwards.
        r = nurbsreg.project(model, points[:5000])
        assert (r.status == 0).all()
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env=os.environ, timeout=TIMEOUT)
    assert done.returncode == 0, done.stderr
    word, seconds = done.stdout.split()
    assert word == "interrupted", done.stdout
    assert float(seconds) < LATENCY


def test_ctrl_c_stops_a_long_alignment_and_the_aligner_still_works():
    script = textwrap.dedent(f"""
        import os, signal, threading, time
        import numpy as np, nurbsreg
        model = nurbsreg.load_model({str(PANEL)!r})
        scan = nurbsreg.synth(model, {sized(1_000_000, 100_000)}, noise=0.02,
                              pose=(3, -2, 4, 3, -2, 2), seed=7)
        small = nurbsreg.synth(model, 20_000, noise=0.02, pose=(3, -2, 4, 3, -2, 2), seed=8)
        aligner = nurbsreg.Aligner(model)
        t0 = time.perf_counter()
        threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT)).start()
        try:
            aligner.align(scan.points)
            print("finished", time.perf_counter() - t0)
        except KeyboardInterrupt:
            print("interrupted", time.perf_counter() - t0)
        again = aligner.align(small.points)
        fresh = nurbsreg.align(model, small.points)
        assert (again.T_model_scan == fresh.T_model_scan).all()
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env=os.environ, timeout=TIMEOUT)
    assert done.returncode == 0, done.stderr
    word, seconds = done.stdout.split()
    assert word == "interrupted", done.stdout
    assert float(seconds) < LATENCY
