#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Side-by-side timing of laser_clustering against scikit-learn, in one run.

1. Asks the C++ benchmark for its inputs (--dump_points): the 64 scans'
   points and the 100k-point 3-D cloud, as exact hex floats.
2. Runs the C++ benchmarks (Google Benchmark, CPU time, median of repeats).
3. Times scikit-learn's DBSCAN in this process on the very same points,
   timing only fit() (CPU time), with the same eps / min_samples: for a scan,
   the two passes the two-stage clustering makes (stage-1 and stage-3
   parameters); for the cloud, one pass.
4. Prints a Markdown table (the one in docs/benchmarks.md).

usage: .venv/bin/python bench/laser_clustering/side_by_side.py [--build build] [--repetitions N]
"""
import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np
import sklearn
from sklearn.cluster import DBSCAN


def read_dump(path):
    scans, cloud, params = [], None, None
    with open(path) as f:
        lines = f.read().split("\n")
    i = 0
    while i < len(lines):
        head = lines[i].split()
        i += 1
        if not head:
            continue
        if head[0] == "params":
            v = head[1:]
            params = dict(eps1=float.fromhex(v[0]), min1=int(v[1]), eps3=float.fromhex(v[2]), min3=int(v[3]),
                          eps_cloud=float.fromhex(v[4]), min_cloud=int(v[5]))
        elif head[0] in ("scan", "cloud"):
            n = int(head[1])
            pts = np.array([[float.fromhex(x) for x in lines[i + k].split()] for k in range(n)], dtype=np.float64)
            i += n
            if head[0] == "scan":
                scans.append(pts)
            else:
                cloud = pts
        else:
            raise SystemExit(f"{path}:{i}: unexpected line {lines[i-1]!r}")
    return params, scans, cloud


def cpu_ns(fn, repeats):
    best = []
    for _ in range(repeats):
        t0 = time.process_time_ns()
        fn()
        best.append(time.process_time_ns() - t0)
    return float(np.median(best))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default="build", help="the CMake build directory")
    ap.add_argument("--repetitions", type=int, default=5)
    args = ap.parse_args()
    exe = os.path.join(args.build, "bench", "laser_clustering", "laser_clustering_bench")
    if not os.path.exists(exe):
        raise SystemExit(f"{exe} not found: build the target laser_clustering_bench first")

    with tempfile.TemporaryDirectory() as tmp:
        dump = os.path.join(tmp, "points.txt")
        subprocess.run([exe, f"--dump_points={dump}"], check=True)
        params, scans, cloud = read_dump(dump)
        out = os.path.join(tmp, "bench.json")
        subprocess.run([exe, f"--benchmark_repetitions={args.repetitions}", "--benchmark_report_aggregates_only=true",
                        f"--benchmark_out={out}", "--benchmark_out_format=json"], check=True,
                       stdout=subprocess.DEVNULL)
        with open(out) as f:
            bench = json.load(f)

    ours = {}
    for b in bench["benchmarks"]:
        if b.get("aggregate_name") != "median":
            continue
        scale = {"ns": 1.0, "us": 1e3, "ms": 1e6, "s": 1e9}[b["time_unit"]]
        ours[b["run_name"]] = b["cpu_time"] * scale  # ns

    # scikit-learn on the same points: both passes per scan.
    # Time only fit(): the estimators are built outside the timed region.
    def sk_fit_only():
        total = 0
        for pts in scans:
            a = DBSCAN(eps=params["eps1"], min_samples=params["min1"])
            b = DBSCAN(eps=params["eps3"], min_samples=params["min3"])
            t0 = time.process_time_ns()
            a.fit(pts)
            b.fit(pts)
            total += time.process_time_ns() - t0
        return total

    sk_scan_ns = float(np.median([sk_fit_only() for _ in range(args.repetitions)])) / len(scans)
    cloud_model = DBSCAN(eps=params["eps_cloud"], min_samples=params["min_cloud"])
    sk_cloud_ns = cpu_ns(lambda: cloud_model.fit(cloud), max(1, args.repetitions // 2))

    rows = [
        ("Two-stage clustering + pedicel finding (ordered-scan fast path)", ours["BM_TwoStagePlusPedicel"]),
        ("  of which the stage-1 DBSCAN pass alone", ours["BM_OrderedScanDbscanStage1"]),
        ("Same two DBSCAN passes, FLANN kd-tree path", ours["BM_FlannDbscanTwoPasses"]),
        ("Same two DBSCAN passes, brute force O(n^2)", ours["BM_BruteForceDbscanTwoPasses"]),
        (f"Same two DBSCAN passes, scikit-learn {sklearn.__version__} fit() (in-process)", sk_scan_ns),
    ]
    print(f"Per 256-pixel scan ({len(scans)} scans, {sum(len(s) for s in scans) / len(scans):.0f} valid pixels on"
          f" average; CPU time, median of {args.repetitions} repetitions; {platform.processor() or platform.machine()},"
          f" {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f})\n")
    print("| what | time per scan |\n|---|---:|")
    for name, ns in rows:
        print(f"| {name} | {ns / 1e3:.1f} us |")
    print(f"\nDBSCAN on 3-D surface clouds (eps {params['eps_cloud']} m, min {params['min_cloud']}, constant density)\n")
    print("| points | FLANN path | brute force | scikit-learn fit() |\n|---:|---:|---:|---:|")
    for n in (1000, 10000, 100000):
        flann = ours.get(f"BM_FlannDbscan3D/{n}")
        brute = ours.get(f"BM_BruteForceDbscan3D/{n}/iterations:2")
        sk = f"{sk_cloud_ns / 1e6:.1f} ms" if n == 100000 else "-"
        print(f"| {n} | {flann / 1e6:.2f} ms | {(f'{brute / 1e6:.1f} ms' if brute else '-')} | {sk} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
