#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Cyclone DDS alone beside tinyline's bridged graph, in one run.

Runs dds_bench's Engine (Cyclone alone: same sertype, QoS, configuration and
bytes, relaying on its receive thread) and Dds (two tinyline processes through
their bridges) cases, then Cyclone's own `ddsperf ping`/`pong` on the same
configuration, and prints one table per measure with the ratios. The load
average before and after goes with the figures.

    bench/dds/side_by_side.py [--bench build/bench/dds/dds_bench] [--repetitions 3]
                              [--ddsperf-seconds 6] [--no-ddsperf] [--shm]

--shm adds ddsperf over Cyclone's shared memory (iceoryx; Debian's build has
it) with SharedMemory enabled in the same configuration: beside the RouDi
that runs (bench/dds/with_roudi.sh), or an `iox-roudi` (Debian package
iceoryx) it starts for the run with the project's pools (config/roudi.toml).

Round trips: p50 / p99 in microseconds (the median of the repetitions' own
p50 and p99). ddsperf prints half the round trip; the table doubles it.
Stream: messages per second through the round trip with 64 in flight.
"""
import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import time

SIZES = [64, 2048, 65536, 1 << 20]


def load():
    return os.getloadavg()


def run_bench(bench, repetitions, env):
    cmd = [bench, "--benchmark_filter=^BM_(Engine|Dds)_(RoundTrip|Stream)/",
           f"--benchmark_repetitions={repetitions}", "--benchmark_report_aggregates_only=true",
           "--benchmark_format=json"]
    out = subprocess.run(cmd, env=env, check=True, capture_output=True, text=True).stdout
    rows = {}
    for b in json.loads(out)["benchmarks"]:
        # The median of the repetitions (a single run when there is one).
        if b.get("aggregate_name", "median" if repetitions == 1 else "") != "median":
            continue
        m = re.match(r"BM_(Engine|Dds)_(RoundTrip|Stream)/(\d+)/", b["run_name"])
        who, kind, size = m.group(1), m.group(2), int(m.group(3))
        if kind == "RoundTrip":
            rows[(who, kind, size)] = (b["p50_us"], b["p99_us"])
        else:
            rows[(who, kind, size)] = (b["items_per_second"],)
    return cmd, rows


def with_shared_memory(config):
    return config.replace("</Domain>", "<SharedMemory><Enable>true</Enable><LogLevel>warn</LogLevel>"
                                       "</SharedMemory></Domain>", 1)


def run_ddsperf(config, domain, size, seconds):
    """Median over the per-second lines (the first one dropped) of ddsperf's p50/p99, doubled."""
    env = dict(os.environ, CYCLONEDDS_URI=config)
    pong = subprocess.Popen(["ddsperf", "-i", str(domain), "-D", str(seconds + 2), "pong"], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        out = subprocess.run(["ddsperf", "-i", str(domain), "-D", str(seconds), "ping", "size", str(size)], env=env,
                             capture_output=True, text=True, timeout=seconds + 30).stdout
    finally:
        pong.terminate()
        pong.wait()
    p50, p99 = [], []
    for line in out.splitlines():
        m = re.search(r" 50% ([\d.]+)us .* 99% ([\d.]+)us", line)
        if m:
            p50.append(2 * float(m.group(1)))
            p99.append(2 * float(m.group(2)))
    if len(p50) < 2:
        raise RuntimeError(f"ddsperf printed no round trips for size {size}:\n{out}")
    return statistics.median(p50[1:]), statistics.median(p99[1:])


def roudi_answers():
    """Whether a RouDi runs here (it listens on a datagram socket in /tmp)."""
    import socket
    s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    try:
        s.connect("/tmp/roudi")
        return True
    except OSError:
        return False
    finally:
        s.close()


def start_roudi():
    """None if a RouDi runs already; otherwise one started with the project's pools."""
    if roudi_answers():
        return None
    pools = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "config", "roudi.toml")
    roudi = subprocess.Popen(["iox-roudi", "-c", pools], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    for _ in range(100):  # RouDi maps its pools before clients may register
        if roudi_answers():
            break
        time.sleep(0.1)
    return roudi


def size_name(n):
    return f"{n >> 20} MiB" if n >= 1 << 20 else f"{n >> 10} KiB" if n >= 1024 else f"{n} B"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bench", default="build/bench/dds/dds_bench")
    ap.add_argument("--repetitions", type=int, default=3)
    ap.add_argument("--ddsperf-seconds", type=int, default=6)
    ap.add_argument("--no-ddsperf", action="store_true")
    ap.add_argument("--shm", action="store_true")
    a = ap.parse_args()
    use_ddsperf = not a.no_ddsperf and shutil.which("ddsperf")
    if a.shm and not (use_ddsperf and shutil.which("iox-roudi")):
        ap.error("--shm needs ddsperf and iox-roudi (apt-get install cyclonedds-tools iceoryx)")

    tag = f"side_by_side_{os.getpid()}"
    domain = 1 + os.getpid() % 200
    env = dict(os.environ, DDS_BENCH_TAG=tag, DDS_BENCH_DOMAIN=str(domain))
    config = subprocess.run([a.bench, "--print-config"], env=env, check=True, capture_output=True,
                            text=True).stdout.strip()
    before = load()
    started = time.strftime("%Y-%m-%d %H:%M")
    cmd, rows = run_bench(a.bench, a.repetitions, env)
    ddsperf, shm = {}, {}
    if use_ddsperf:
        for size in SIZES:
            ddsperf[size] = run_ddsperf(config, domain, size, a.ddsperf_seconds)
    if a.shm:
        roudi = start_roudi()
        try:
            for size in SIZES[2:]:
                shm[size] = run_ddsperf(with_shared_memory(config), domain, size, a.ddsperf_seconds)
        finally:
            if roudi is not None:
                roudi.terminate()
                roudi.wait()
    after = load()

    print(f"{started}; load average (1, 5, 15 min) before {before[0]:.2f} {before[1]:.2f} {before[2]:.2f}, "
          f"after {after[0]:.2f} {after[1]:.2f} {after[2]:.2f}")
    print(f"command: {' '.join(cmd)}; ddsperf ping/pong {a.ddsperf_seconds} s per size on the same configuration\n")
    print("Round trip (one message in flight), p50 / p99 us:\n")
    def pair(v):
        return f"{v[0]:.1f} / {v[1]:.1f}" if v else "-"

    print("| payload | Cyclone alone | tinyline | ratio p50 / p99 | ddsperf |" + (" ddsperf, shared memory |" if shm else ""))
    print("|---|---|---|---|---|" + ("---|" if shm else ""))
    for size in SIZES:
        e, t = rows[("Engine", "RoundTrip", size)], rows[("Dds", "RoundTrip", size)]
        print(f"| {size_name(size)} | {pair(e)} | {pair(t)} | {t[0] / e[0]:.2f} / {t[1] / e[1]:.2f} | "
              f"{pair(ddsperf.get(size))} |" + (f" {pair(shm.get(size))} |" if shm else ""))
    print("\nStream (64 in flight), round trips per second:\n")
    print("| payload | Cyclone alone | tinyline | ratio (alone / tinyline) |")
    print("|---|---|---|---|")
    for size in SIZES:
        e, t = rows[("Engine", "Stream", size)][0], rows[("Dds", "Stream", size)][0]
        print(f"| {size_name(size)} | {e:,.0f} /s | {t:,.0f} /s | {e / t:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
