#!/usr/bin/env python3
"""Throughput and latency of `nurbsreg serve` against `nurbsreg batch` on the same frames.

For each model (the freeform panel and a real part, NIST CTC-02), in the same run:
  1. synthesise --distinct frames of --points points (moved and noisy scans, binary PCD);
  2. `nurbsreg batch` over clients x frames of them (symlinks to the distinct files);
  3. `nurbsreg serve` on a loopback ephemeral port, --clients concurrent keep-alive clients
     (http.client) posting --frames frames each to /v1/align, after --warmup warm-up frames each;
and prints frames/s, points/s, the ratio to batch, p50/p95/p99 latency, the server's CPU
seconds per frame (utime + stime of all its threads: less disturbed by a shared machine than the
wall time) and its resident memory (VmRSS, and the peak VmHWM) after the warm-up and at the end.

Bounded: it stops by itself (--max-seconds per stage; a stage cut short says so), and the
server is always killed at the end. The machine is shared: use fewer frames (--frames) there.

  bench/service/service_bench.py [--frames 100] [--clients 8] [--points 100000]
                                 [--models panel,nist] [--threads 0]
  bench/service/service_bench.py --soak 3000 [--points 5000]   # memory over many requests
  bench/service/service_bench.py --session ...   # each client one session (warm frames)

--session: each client streams its frames into its own session, so every frame after the
warm-up starts from the previous frame's pose (ICP only, no global stage): the warm-frame
latency of a camera stream. Batch has no sessions and still runs the global stage per frame.
The load average (1 min) is printed at the start and the end: the machine may be shared.

--soak N: N small frames (--points each, default here 5000) from --clients clients to one
server, the resident memory sampled every N/10 frames: it must stay flat.
"""
import argparse
import http.client
import json
import os
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
MODELS = {
    "panel": (os.path.join(ROOT, "examples", "panel.json"), 0.02),
    "nist": (os.path.join(ROOT, "..", "shared", "data", "real", "nist",
                          "nist_ctc_02_asme1_ap242-1.stp"), 0.01),
}


def run(cmd, **kw):
    return subprocess.run(cmd, check=True, **kw)


def proc_status(pid):
    fields = {}
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            key, _, value = line.partition(":")
            if key in ("VmRSS", "VmHWM"):
                fields[key] = int(value.split()[0]) * 1024
    return fields


def cpu_seconds(pid):
    """utime + stime of a process (every thread), from /proc/PID/stat."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def percentile(values, q):
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * (len(ordered) - 1) + 0.5))] if ordered else float("nan")


def memory_profile(trace, frames):
    """VmRSS (MB) when 10%, 20%, ... 100% of the frames had been answered, from the sampler's
    (frames answered, bytes) trace: the last sample at or before each tenth."""
    out = []
    for tenth in range(1, 11):
        mark = frames * tenth // 10
        below = [rss for done, rss in trace if done <= mark]
        if below:
            out.append(f"{mark}: {below[-1] / 2**20:.0f}")
    return "  ".join(out)


def synth_frames(binary, model, noise, points, distinct, out_dir):
    files = []
    for i in range(distinct):
        pose = f"{0.01 * (i % 3)} {-0.01 * (i % 2)} {0.015} {0.2 * (i % 4)} 0.3 -0.2"
        path = os.path.join(out_dir, f"distinct_{i:03d}.pcd")
        run([binary, "-q", "synth", "--model", model, "--points", str(points), "--noise", str(noise),
             "--seed", str(i + 1), "--pose", pose, "--out", path])
        files.append(path)
    return files


def bench_batch(binary, model, files, total, threads, work, max_seconds):
    scans = os.path.join(work, "batch_scans")
    out = os.path.join(work, "batch_out")
    os.makedirs(scans)
    for k in range(total):
        os.symlink(files[k % len(files)], os.path.join(scans, f"frame_{k:05d}.pcd"))
    start = time.monotonic()
    try:
        run([binary, "-q", "batch", "--model", model, "--scans", scans, "--out", out,
             "--threads", str(threads)], stdout=subprocess.DEVNULL, timeout=max_seconds)
        done = total
    except subprocess.TimeoutExpired:
        done = sum(1 for name in os.listdir(out) if name.endswith(".done.csv"))
    return done, time.monotonic() - start


def bench_serve(binary, model, files, clients, frames, threads, max_seconds, log, session=False,
                time_limit=600, warmup=2):
    server = subprocess.Popen(
        [binary, "serve", "--model", model, "--id", "m", "--port", "0", "--threads", str(threads),
         "--max-inflight", str(clients), "--connections", str(clients + 2),
         "--time-limit", str(time_limit),
         # A client that waits at the barrier for slower warm-ups must find its keep-alive
         # connection still open (the default closes one idle for 5 s).
         "--keep-alive", str(int(max_seconds) + 60)],
        stdout=subprocess.PIPE, stderr=log, text=True)
    try:
        line = server.stdout.readline()
        if not line.startswith("listening on "):
            raise RuntimeError("server did not start: " + line)
        port = int(line.rsplit(":", 1)[1])
        bodies = [open(f, "rb").read() for f in files]
        headers = {"Content-Type": "application/octet-stream"}
        latencies = [[] for _ in range(clients)]
        failures = []
        deadline = [None]
        barrier = threading.Barrier(clients + 1)

        def client(c):
            conn = http.client.HTTPConnection("127.0.0.1", port, timeout=300)
            path = f"/v1/align?model=m&session=client{c}" if session else "/v1/align?model=m"
            def frame(k):
                t = time.monotonic()
                conn.request("POST", path, bodies[k % len(bodies)], headers)
                answer = conn.getresponse()
                text = answer.read()
                if answer.status != 200:
                    failures.append(f"{answer.status}: {text[:200]!r}")
                return time.monotonic() - t
            # Warm-up, --warmup frames (default: every distinct frame once): the first fills an
            # aligner's coarse-stage buffers (and, in a session, is its global frame), the next
            # ones the aligner's own ICP buffers; a pooled aligner's buffers keep the capacity of
            # the largest frame it has run, so the memory is sampled once every client has sent
            # every distinct frame (two frames leave the pool growing for its first ~10%).
            for k in range(warmup):
                frame(c + k)
            barrier.wait()
            for k in range(frames):
                if time.monotonic() > deadline[0]:
                    break
                latencies[c].append(frame(c * frames + k))
            conn.close()

        threads_ = [threading.Thread(target=client, args=(c,)) for c in range(clients)]
        for t in threads_:
            t.start()
        deadline[0] = time.monotonic() + 1e9
        barrier.wait()
        memory_start = proc_status(server.pid)
        cpu_start = cpu_seconds(server.pid)
        start = time.monotonic()
        deadline[0] = start + max_seconds
        # The resident memory along the run (frames answered, VmRSS), sampled every quarter
        # second: the start and end alone cannot tell a plateau from a steady growth.
        rss_trace = []
        sampling = threading.Event()

        def sample_memory():
            while not sampling.wait(0.25):
                rss_trace.append((sum(len(per) for per in latencies),
                                  proc_status(server.pid)["VmRSS"]))
        sampler = threading.Thread(target=sample_memory)
        sampler.start()
        for t in threads_:
            t.join()
        sampling.set()
        sampler.join()
        seconds = time.monotonic() - start
        cpu = cpu_seconds(server.pid) - cpu_start
        memory_end = proc_status(server.pid)
        return ([x for per in latencies for x in per], seconds, memory_start, memory_end, failures,
                cpu, rss_trace)
    finally:
        server.terminate()
        try:
            server.wait(timeout=60)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()


def soak(binary, frames, clients, points, work):
    model, noise = MODELS["panel"]
    files = synth_frames(binary, model, noise, points, 4, work)
    bodies = [open(f, "rb").read() for f in files]
    server = subprocess.Popen([binary, "-q", "serve", "--model", model, "--id", "m", "--port", "0",
                               "--max-inflight", str(clients)],
                              stdout=subprocess.PIPE, text=True)
    try:
        port = int(server.stdout.readline().rsplit(":", 1)[1])
        done = [0]
        lock = threading.Lock()
        samples = []
        step = max(1, frames // 10)

        def client(c):
            conn = http.client.HTTPConnection("127.0.0.1", port, timeout=300)
            k = c
            while True:
                with lock:
                    if done[0] >= frames:
                        return
                    done[0] += 1
                    n = done[0]
                # Alternate plain frames, session frames (a few sessions) and projections.
                path = ["/v1/align?model=m", f"/v1/align?model=m&session=s{k % 5}",
                        "/v1/project?model=m"][k % 3]
                conn.request("POST", path, bodies[k % len(bodies)],
                             {"Content-Type": "application/octet-stream"})
                answer = conn.getresponse()
                answer.read()
                if answer.status != 200:
                    raise RuntimeError(f"{path}: {answer.status}")
                if n % step == 0:
                    with lock:
                        samples.append((n, proc_status(server.pid)["VmRSS"]))
                k += clients
        threads_ = [threading.Thread(target=client, args=(c,)) for c in range(clients)]
        for t in threads_:
            t.start()
        for t in threads_:
            t.join()
        samples.sort()
        print(f"soak: {frames} requests ({points} points, align / session align / project), "
              f"{clients} clients; resident MB after n requests:")
        print("  " + "  ".join(f"{n}: {rss / 2**20:.1f}" for n, rss in samples))
        first, last = samples[0][1], samples[-1][1]
        print(f"  first sample -> last: {100 * (last - first) / first:+.1f}%")
    finally:
        server.terminate()
        server.wait(timeout=60)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--frames", type=int, default=100, help="frames per client")
    p.add_argument("--clients", type=int, default=8)
    p.add_argument("--points", type=int, default=100000)
    p.add_argument("--distinct", type=int, default=8, help="distinct synthetic frames per model")
    p.add_argument("--models", default="panel,nist")
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--max-seconds", type=float, default=900, help="per stage")
    p.add_argument("--binary", default=os.path.join(ROOT, "build", "bin", "nurbsreg"))
    p.add_argument("--soak", type=int, default=0, help="memory soak: this many small requests")
    p.add_argument("--warmup", type=int,
                   help="warm-up frames per client before the measured ones (default: --distinct)")
    p.add_argument("--no-batch", action="store_true",
                   help="the service alone (no batch stage, no ratio): memory and latency runs")
    p.add_argument("--session", action="store_true", help="each client one session (warm frames)")
    p.add_argument("--time-limit", type=float, default=600,
                   help="the server's --time-limit (s): frames over it are answered 504 and count "
                        "as failed")
    a = p.parse_args()
    load_start = os.getloadavg()[0]
    if a.soak:
        with tempfile.TemporaryDirectory(prefix="nurbsreg-service-soak-") as work:
            soak(a.binary, a.soak, a.clients, a.points if a.points != 100000 else 5000, work)
        print(f"load average (1 min): {load_start:.1f} at the start, {os.getloadavg()[0]:.1f} at the end")
        return 0
    rows = []
    with tempfile.TemporaryDirectory(prefix="nurbsreg-service-bench-") as work:
        log = open(os.path.join(work, "serve.log"), "w")
        for name in a.models.split(","):
            model, noise = MODELS[name]
            model_work = os.path.join(work, name)
            os.makedirs(model_work)
            print(f"[{name}] synthesising {a.distinct} frames of {a.points} points ...", flush=True)
            files = synth_frames(a.binary, model, noise, a.points, a.distinct, model_work)
            total = a.clients * a.frames
            if a.no_batch:
                batch_done, batch_seconds = 0, float("nan")
            else:
                print(f"[{name}] batch over {total} frames ...", flush=True)
                batch_done, batch_seconds = bench_batch(a.binary, model, files, total, a.threads,
                                                        model_work, a.max_seconds)
            print(f"[{name}] serve: {a.clients} clients x {a.frames} frames ...", flush=True)
            latencies, seconds, m0, m1, failures, cpu, rss_trace = bench_serve(
                a.binary, model, files, a.clients, a.frames, a.threads, a.max_seconds, log,
                a.session, a.time_limit, a.warmup if a.warmup is not None else len(files))
            if failures:
                print(f"[{name}] {len(failures)} failed frames, first: {failures[0]}")
            served = len(latencies)
            print(f"[{name}] resident MB by frames answered: " + memory_profile(rss_trace, served),
                  flush=True)
            batch_fps = batch_done / batch_seconds
            serve_fps = served / seconds
            rows.append({
                "model": name, "frames": served, "batch_frames": batch_done,
                "serve_fps": serve_fps, "batch_fps": batch_fps,
                "serve_pps": serve_fps * a.points, "batch_pps": batch_fps * a.points,
                "ratio": serve_fps / batch_fps,
                "p50": percentile(latencies, 0.5), "p95": percentile(latencies, 0.95),
                "p99": percentile(latencies, 0.99),
                "rss_start": m0["VmRSS"], "rss_end": m1["VmRSS"],
                "hwm_start": m0["VmHWM"], "hwm_end": m1["VmHWM"],
                "cpu_ms": 1e3 * cpu / max(served, 1),
                "cut_short": served < total or (batch_done < total and not a.no_batch), "failed": len(failures)})
    print()
    print(f"{a.clients} clients{' (one session each)' if a.session else ''}, {a.points} points a "
          f"frame, threads {a.threads or 'all'}, {os.cpu_count()} hardware threads, load average "
          f"(1 min) {load_start:.1f} at the start, {os.getloadavg()[0]:.1f} at the end")
    print("| model | frames (serve/batch) | serve frames/s | batch frames/s | serve/batch | "
          "serve Mpoints/s | p50 ms | p95 ms | p99 ms | server CPU ms/frame | RSS start -> end MB | "
          "peak RSS start -> end MB |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['model']} | {r['frames']}/{r['batch_frames']}{' (cut short)' if r['cut_short'] else ''} "
              f"| {r['serve_fps']:.2f} | {r['batch_fps']:.2f} | {r['ratio']:.2f} | {r['serve_pps'] / 1e6:.2f} "
              f"| {1e3 * r['p50']:.0f} | {1e3 * r['p95']:.0f} | {1e3 * r['p99']:.0f} | {r['cpu_ms']:.0f} "
              f"| {r['rss_start'] / 2**20:.0f} -> {r['rss_end'] / 2**20:.0f} "
              f"| {r['hwm_start'] / 2**20:.0f} -> {r['hwm_end'] / 2**20:.0f} |")
    print(json.dumps(rows))
    return 1 if any(r["failed"] for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
