"""Python call overhead of nurbsreg (bench/README.md, "Python"): in one run,

1. project 1,000,000 points of the example panel through nurbsreg.project and through the C++ API
   (build/bench/python/python_baseline on the same file), rounds alternating between the two so
   that the shared machine's load falls on both alike;
2. two Python threads projecting at once against the same two frames one after the other (the
   GIL is released during a call), with threads=1 per call and with all threads;
3. aligning a 1,000,000-point scan from Python (nurbsreg.align from any pose: the global stage,
   then ICP), and the CLI's whole run on the same points (same pose bits), rounds alternating.

    PYTHONPATH=build/python /usr/bin/python3 bench/python/bench_python.py [--rounds 3]

Bounded: about a minute on two cores. Prints a table; medians over the rounds.
"""

import argparse
import json
import pathlib
import resource
import statistics
import subprocess
import tempfile
import threading
import time

import numpy as np

import nurbsreg

ROOT = pathlib.Path(__file__).resolve().parents[2]


def timed(call):
    start = time.perf_counter()
    result = call()
    return time.perf_counter() - start, result


def timed_cpu(call):
    """Wall and process CPU seconds (every thread) of one call."""
    start, cpu = time.perf_counter(), time.process_time()
    call()
    return time.perf_counter() - start, time.process_time() - cpu


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--build", default=str(ROOT / "build"))
    args = parser.parse_args()
    model_path = ROOT / "examples" / "panel.json"
    model = nurbsreg.load_model(model_path)
    baseline = pathlib.Path(args.build) / "bench" / "python" / "python_baseline"

    with tempfile.TemporaryDirectory() as tmp:
        # Scan-like points: area samples with 0.05 mm noise, in the model frame (no pose).
        scan = nurbsreg.synth(model, args.points, noise=0.05, seed=1)
        path = pathlib.Path(tmp) / "points.pcd"
        nurbsreg.write_point_cloud(path, scan.points, double_precision=True)
        points = nurbsreg.read_point_cloud(path).points
        nurbsreg.project(model, points[:10000])  # the projector pool's scratch

        wall = {"python": [], "fresh": [], "reused": []}
        cpu = {"python": [], "fresh": [], "reused": []}
        for _ in range(args.rounds):
            done = subprocess.run([str(baseline), str(model_path), str(path), "3"],
                                  capture_output=True, text=True, check=True)
            cpp = json.loads(done.stdout)
            for kind in ("fresh", "reused"):
                wall[kind] += cpp[kind]
                cpu[kind] += cpp[kind + "_cpu"]
            for _ in range(3):
                w, c = timed_cpu(lambda: nurbsreg.project(model, points))
                wall["python"].append(w)
                cpu["python"].append(c)
        med = {k: (statistics.median(wall[k]), statistics.median(cpu[k])) for k in wall}
        py_wall, py_cpu = med["python"]
        print(f"project {len(points):,} points (panel, all threads), median of "
              f"{len(wall['python'])} calls each, alternating rounds (wall / CPU seconds):")
        print(f"  nurbsreg.project (Python)         {py_wall:7.3f} / {py_cpu:7.3f} s  "
              f"{len(points) / py_wall / 1e6:5.2f} M points/s")
        for kind, label in (("fresh", "fresh results"), ("reused", "reused       ")):
            w, c = med[kind]
            print(f"  Projector::project, {label} {w:7.3f} / {c:7.3f} s  ratio Python / C++ "
                  f"{py_wall / w:5.3f} wall, {py_cpu / c:5.3f} CPU")

        # Two frames, each projected on one thread or on all, one after the other or in two
        # Python threads at once.
        frames = [points[: len(points) // 2], points[len(points) // 2:]]
        for threads in (1, None):
            serial_s, parallel_s = [], []
            for _ in range(args.rounds):
                serial_s.append(timed(lambda: [nurbsreg.project(model, f, threads=threads)
                                               for f in frames])[0])

                def both():
                    workers = [threading.Thread(target=nurbsreg.project, args=(model, f),
                                                kwargs={"threads": threads}) for f in frames]
                    for w in workers:
                        w.start()
                    for w in workers:
                        w.join()

                parallel_s.append(timed(both)[0])
            s, p = statistics.median(serial_s), statistics.median(parallel_s)
            label = "threads=1" if threads == 1 else "all threads"
            print(f"two frames of {len(frames[0]):,} points, {label}: one after the other "
                  f"{s:6.3f} s, two Python threads at once {p:6.3f} s (speed-up {s / p:4.2f})")

        # A 1 M-point scan moved by a few degrees and millimetres.
        moved = nurbsreg.synth(model, args.points, noise=0.02, pose=(3, -2, 4, 3, -2, 2), seed=7)
        # The CLI on the same points (a float64 PCD): its whole run, and the same pose; rounds
        # alternate between the two.
        scan_path = pathlib.Path(tmp) / "scan.pcd"
        nurbsreg.write_point_cloud(scan_path, moved.points, double_precision=True)
        cli = pathlib.Path(args.build) / "bin" / "nurbsreg"
        python_runs, cli_runs = [], []
        for _ in range(args.rounds):
            start, cpu = time.perf_counter(), time.process_time()
            result = nurbsreg.align(model, moved.points)
            python_runs.append((time.perf_counter() - start, time.process_time() - cpu,
                                result.coarse.seconds))
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            start = time.perf_counter()
            subprocess.run([str(cli), "align", "--model", str(model_path), "--scan",
                            str(scan_path), "--out-pose", str(pathlib.Path(tmp) / "pose.txt")],
                           capture_output=True, check=True)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cli_runs.append((time.perf_counter() - start, after.ru_utime + after.ru_stime
                             - before.ru_utime - before.ru_stime))
        wall, cpu, icp = (statistics.median(r[k] for r in python_runs) for k in range(3))
        cli_wall, cli_cpu = (statistics.median(r[k] for r in cli_runs) for k in range(2))
        error = np.abs(result.T_model_scan - moved.T_model_scan).max()
        pose = np.loadtxt(pathlib.Path(tmp) / "pose.txt")
        print(f"align {len(moved.points):,} points (wall / CPU seconds, median of {args.rounds}):")
        print(f"  nurbsreg.align (Python)                    {wall:6.3f} / {cpu:6.3f} s (coarse "
              f"stage {icp:.3f} s), {result.iterations} iterations, rms {result.rms:.4f}, fit "
              f"{result.fit.fit}, max |T - T_true| {error:.1e}")
        print(f"  nurbsreg align (CLI, incl. reading the file) {cli_wall:6.3f} / {cli_cpu:6.3f} s; "
              f"same pose as Python: {bool((pose == result.T_model_scan).all())}")


if __name__ == "__main__":
    main()
