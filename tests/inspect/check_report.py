#!/usr/bin/python3
"""The inspection report in a real browser and the PLY in Open3D (ctest inspect_browser_and_open3d).

Makes a small noisy scan of the example panel, runs `nurbsreg inspect` on it, then:
  - Open3D (tensor API) reads deviations.ply: the same points, colours, signed_distance and face as
    a direct parse of the binary records, and the signed distances give inspect.json's numbers;
  - headless Chromium opens report.html from disk with the network off (a dead proxy): the page's
    self-check (#selfcheck, written by the page's script) says the 3-D view was drawn in the colour
    map's colours and no script error happened, the console shows no error, every number shown
    (data-key / data-value) equals inspect.json's, and a screenshot's viewer area holds colour-map
    colours.
Usage: check_report.py --binary path/to/nurbsreg --examples path/to/examples [--keep DIR]
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

import numpy as np
import open3d as o3d

FAILURES = []


def check(condition, message):
    if not condition:
        FAILURES.append(message)
        print("FAIL:", message)


def run(args, **kw):
    r = subprocess.run(args, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.exit(f"{' '.join(args)} failed ({r.returncode}): {r.stderr.strip()}")
    return r


def chromium(args, timeout=90):
    base = ["chromium", "--headless", "--no-sandbox", "--disable-gpu-sandbox",
            "--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
            "--ignore-gpu-blocklist",
            # The network off: every request would go to a dead proxy.
            "--proxy-server=127.0.0.1:9", "--proxy-bypass-list=<-loopback>",
            "--no-first-run", "--disable-extensions", "--disable-background-networking",
            "--enable-logging=stderr", "--v=0", "--virtual-time-budget=20000",
            "--allow-file-access-from-files"]
    return subprocess.run(base + args, capture_output=True, text=True, timeout=timeout)


def ply_records(path):
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode()
    types = {"float": "<f4", "double": "<f8", "uchar": "u1", "char": "i1", "int": "<i4", "uint": "<u4"}
    vertex = header.split("element vertex")[1]
    count = int(vertex.split()[0])
    fields = [(name, types[t]) for t, name in re.findall(r"property (\w+) (\w+)", vertex.split("element")[0])]
    return header, np.frombuffer(data[end:], dtype=np.dtype(fields), count=count)


def check_ply(out, report):
    header, rec = ply_records(os.path.join(out, "deviations.ply"))
    check("format binary_little_endian 1.0" in header, "PLY is binary little-endian")
    pcd = o3d.t.io.read_point_cloud(os.path.join(out, "deviations.ply"))
    pos = pcd.point.positions.numpy()
    check(pos.shape == (len(rec), 3), f"Open3D reads {len(rec)} points (got {pos.shape})")
    check(np.array_equal(pos, np.stack([rec["x"], rec["y"], rec["z"]], axis=1)), "Open3D points equal the records")
    colours = pcd.point.colors.numpy()
    rgb = np.stack([rec["red"], rec["green"], rec["blue"]], axis=1)
    # Open3D gives uchar colours as they are, or as floats in [0, 1].
    if colours.dtype != np.uint8:
        colours = np.round(colours * 255).astype(np.uint8)
    check(np.array_equal(colours, rgb), "Open3D colours equal the records")
    for field in ("signed_distance", "face"):
        check(field in pcd.point, f"Open3D sees the field {field}")
        if field in pcd.point:
            values = pcd.point[field].numpy().reshape(-1)
            check(np.array_equal(values, rec[field].astype(values.dtype)), f"Open3D {field} equals the records")
    d = rec["signed_distance"].astype(np.float64)
    check(len(d) == report["points"], "PLY has every inspected point")
    # float32 in the file against double statistics.
    check(abs(d.mean() - report["mean"]) < 1e-6, f"PLY mean {d.mean()} vs inspect.json {report['mean']}")
    check(abs(np.percentile(d, 95) - report["p95"]) < 1e-6, "PLY p95 vs inspect.json")
    lo, hi = report["tolerance"]["lower"], report["tolerance"]["upper"]
    check(abs(np.mean((d >= lo) & (d <= hi)) - report["inside_tolerance"]) < 2.0 / len(d), "PLY inside share")
    # Open3D's legacy reader (what most scripts use) gets points and colours too.
    legacy = o3d.io.read_point_cloud(os.path.join(out, "deviations.ply"))
    check(len(legacy.points) == len(rec) and legacy.has_colors(), "Open3D legacy reader: points and colours")


def check_cloudcompare(out):
    """CloudCompare's command line (what its GUI does too, without the PLY dialog) loads the PLY
    with its colours and the signed distance as a scalar field."""
    if shutil.which("CloudCompare") is None:
        print("CloudCompare not installed: its check skipped")
        return
    saved = os.path.join(out, "cc_saved.ply")
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen")
    r = subprocess.run(["CloudCompare", "-SILENT", "-AUTO_SAVE", "OFF", "-C_EXPORT_FMT", "PLY",
                        "-PLY_EXPORT_FMT", "BINARY_LE", "-O", os.path.join(out, "deviations.ply"),
                        "-SAVE_CLOUDS", "FILE", saved], capture_output=True, text=True, env=env, timeout=120)
    check(r.returncode == 0 and os.path.exists(saved), f"CloudCompare opens and saves the PLY: {r.stdout[-300:]}")
    if not os.path.exists(saved):
        return
    _, ours = ply_records(os.path.join(out, "deviations.ply"))
    _, cc = ply_records(saved)
    check(len(cc) == len(ours), "CloudCompare sees every point")
    check("scalar_signed_distance" in cc.dtype.names, f"CloudCompare loads the signed distance as a scalar field: {cc.dtype.names}")
    if len(cc) == len(ours) and "scalar_signed_distance" in cc.dtype.names:
        check(np.array_equal(cc["scalar_signed_distance"], ours["signed_distance"]), "CloudCompare's scalar field equals signed_distance")
        check(np.array_equal(cc["red"], ours["red"]) and np.array_equal(cc["blue"], ours["blue"]), "CloudCompare's colours")


def expected_value(report, key):
    simple = {"alignment_rms": report["rms"], "tolerance_lower": report["tolerance"]["lower"],
              "tolerance_upper": report["tolerance"]["upper"], "viewer_points": report["viewer"]["points"]}
    if key in simple:
        return simple[key]
    if key in ("above_fraction", "below_fraction"):
        return report[key.split("_")[0]] / report["points"]
    return report[key]


def check_page(out, report):
    page = "file://" + os.path.abspath(os.path.join(out, "report.html"))
    r = chromium(["--dump-dom", page])
    dom = r.stdout
    m = re.search(r'<div id="selfcheck"([^>]*)>', dom)
    check(m is not None, "the page's self-check element is in the DOM")
    attrs = dict(re.findall(r'data-([\w-]+)="([^"]*)"', m.group(1))) if m else {}
    print("self-check:", attrs)
    check(attrs.get("status") == "ok", f"self-check status ok (got {attrs.get('status')}, errors: {attrs.get('errors')})")
    check(attrs.get("errors", "x") == "", f"no script errors: {attrs.get('errors')}")
    check(int(attrs.get("coloured-pixels", 0)) > 1000, "the 3-D canvas shows colour-map pixels")
    check(int(attrs.get("points", 0)) == report["viewer"]["points"], "the view draws the stated subset")
    check(attrs.get("hover") == "ok", "hovering over a point shows its deviation")
    console = [line for line in r.stderr.splitlines() if "CONSOLE" in line or "Uncaught" in line]
    check(not any(("rror" in line or "Uncaught" in line) for line in console), f"no console errors: {console}")

    shown = re.findall(r'<span data-key="(\w+)" data-value="([^"]*)">([^<]*)</span>', dom)
    keys = {k for k, _, _ in shown}
    for needed in ("inside_tolerance", "mean", "std", "min", "max", "p5", "p95", "points", "tolerance_lower", "tolerance_upper"):
        check(needed in keys, f"the page shows {needed}")
    for key, value, text in shown:
        want = expected_value(report, key)
        check(value != "" and float(value) == float(want), f"{key}: page {value} vs inspect.json {want}")
    for key, fmt in (("mean", "{:+.4f}"), ("min", "{:+.4f}"), ("p95", "{:+.4f}"), ("std", "{:.4f}")):
        texts = [t for k, _, t in shown if k == key]
        check(texts and texts[0] == fmt.format(report[key]), f"{key} shown as {texts} vs {fmt.format(report[key])}")
    texts = [t for k, _, t in shown if k == "inside_tolerance"]
    check(texts and texts[0] == "{:.2f} %".format(100 * report["inside_tolerance"]), f"inside shown as {texts}")
    verdict = re.search(r'data-key="verdict" data-value="(\w+)"', dom)
    check(verdict and verdict.group(1) == report["verdict"], "verdict shown")
    rows = re.findall(r'<tr data-face="(\d+)"[^>]*>(.*?)</tr>', dom)
    check(len(rows) == len(report["faces"]), "one table row per face")
    for face, cells in rows:
        values = re.findall(r'<td data-value="([^"]*)"', cells)
        f = report["faces"][int(face)]
        for value, key in zip(values[2:], ("points", "mean", "std", "min", "max", "p5", "p95", "inside_tolerance")):
            want = f[key]
            check((value == "" and want is None) or float(value) == float(want), f"face {face} {key}: {value} vs {want}")

    shot = os.path.join(out, "screenshot.png")
    r = chromium(["--screenshot=" + shot, "--window-size=1400,1000", "--hide-scrollbars", page])
    check(os.path.exists(shot), f"screenshot written ({r.stderr[-300:]})")
    if os.path.exists(shot):
        img = np.asarray(o3d.io.read_image(shot))[:, :, :3].astype(int)
        # The band colour of the metrology scale and any strongly coloured (non-grey) pixel.
        band = np.all(np.abs(img - np.array([70, 185, 90])) <= 40, axis=2)
        saturated = (img.max(axis=2) - img.min(axis=2)) > 60
        print(f"screenshot: {band.sum()} band-coloured pixels, {saturated.sum()} saturated pixels")
        check(band.sum() > 500, "the screenshot shows the tolerance band colour")
        check(saturated.sum() > 2000, "the screenshot shows colour-map colours")
        os.remove(shot)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--binary", required=True)
    ap.add_argument("--examples", required=True)
    ap.add_argument("--keep")
    a = ap.parse_args()
    if shutil.which("chromium") is None:
        sys.exit("chromium not found (scripts/install_deps.sh installs it)")
    work = tempfile.mkdtemp(prefix="nurbsreg-inspect-check-")
    try:
        panel = os.path.join(a.examples, "panel.json")
        scan = os.path.join(work, "scan.pcd")
        run([a.binary, "-q", "synth", "--model", panel, "--points", "8000", "--noise", "0.02", "--seed", "9", "--out", scan])
        pose = os.path.join(work, "identity.txt")
        with open(pose, "w") as f:
            f.write("1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n")
        out = os.path.join(work, "out")
        run([a.binary, "-q", "inspect", "--model", panel, "--scan", scan, "--pose", pose,
             "--tolerance", "0.02", "--out-dir", out])
        with open(os.path.join(out, "inspect.json")) as f:
            report = json.load(f)
        check_ply(out, report)
        check_cloudcompare(out)
        check_page(out, report)
        if a.keep:
            shutil.copytree(out, a.keep, dirs_exist_ok=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    if FAILURES:
        sys.exit(f"{len(FAILURES)} check(s) failed")
    print("all checks passed")


if __name__ == "__main__":
    main()
