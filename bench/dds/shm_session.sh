#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Every shared-memory figure of docs/benchmarks.md ("Large messages and shared
# memory") in one session, beside one RouDi (bench/dds/with_roudi.sh runs this
# script inside its private mount namespace):
#   bench/dds/with_roudi.sh bench/dds/shm_session.sh [BUILD]
# 1. round trips at 64 KiB, 1 MiB and a VGA cloud: Cyclone alone over loopback
#    (the reference), tinyline over loopback, the in-process floor;
# 2. the same over shared memory: Cyclone alone, tinyline;
# 3. side_by_side.py --shm: ddsperf over loopback and over shared memory.
set -euo pipefail
build=${1:-build}
here=$(dirname "$(readlink -f "$0")")
sizes='(65536|1048576|9830400)'
uptime
echo "== loopback: Cyclone alone (Engine), tinyline (Dds), in one process"
"$build/bench/dds/dds_bench" --benchmark_filter="^BM_(Engine|Dds|InProcess)_RoundTrip/$sizes/"
echo "== shared memory: Cyclone alone (Engine), tinyline (Dds)"
DDS_BENCH_SHM=1 "$build/bench/dds/dds_bench" --benchmark_filter="^BM_(Engine|Dds)_RoundTrip/$sizes/"
echo "== side by side with ddsperf, loopback and shared memory"
python3 "$here/side_by_side.py" --bench "$build/bench/dds/dds_bench" --repetitions 1 --ddsperf-seconds 3 --shm
uptime
