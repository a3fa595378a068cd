#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Centre error of a live `launch/hydrus_grasp.launch.yaml` run, from an MCAP
bag of /hydrus/circle and /hydrus/truth (docs/hydrus_fitting.md).

Each fit is compared with the truth sample nearest its stamp; rows per phase
of the manoeuvre (times from the first truth sample; the run must stop before
the manoeuvre loops, at 12 s).

    .venv/bin/python scripts/plots/hydrus_live.py /tmp/live.mcap
"""
import bisect
import math
import statistics as st
import sys

from mcap_ros2.reader import read_ros2_messages

PHASES = [("approach", 0.0, 6.0), ("closing", 6.0, 10.0), ("hold", 10.0, 12.0)]


def main(argv):
    if len(argv) != 2:
        print(__doc__)
        return 2
    truth, fits = [], []
    for m in read_ros2_messages(argv[1]):
        msg = m.ros_msg
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        if m.channel.topic.endswith("/truth"):
            truth.append((t, msg.centre.x, msg.centre.y, msg.radius_m))
        elif m.channel.topic.endswith("/circle"):
            fits.append((t, msg.status, msg.centre.x, msg.centre.y, msg.radius_m))
    if not truth or not fits:
        print(f"{argv[1]}: needs /hydrus/truth and /hydrus/circle messages")
        return 1
    truth.sort()
    ts = [x[0] for x in truth]
    t0 = ts[0]
    print("| phase | fits | ok | median centre error [mm] | 95th pct [mm] | fits > 2 cm | median radius error [mm] |")
    print("|---|---|---|---|---|---|---|")
    for name, a, b in PHASES:
        errs, rad, n = [], [], 0
        for f in fits:
            if not a <= f[0] - t0 < b:
                continue
            n += 1
            if f[1] != 0:
                continue
            tr = truth[min(bisect.bisect_left(ts, f[0]), len(ts) - 1)]
            errs.append(1000 * math.hypot(f[2] - tr[1], f[3] - tr[2]))
            rad.append(1000 * (f[4] - tr[3]))
        if not errs:
            continue
        errs.sort()
        p95 = errs[int(0.95 * (len(errs) - 1))]
        big = sum(1 for e in errs if e > 20)
        print(f"| {name} | {n} | {len(errs)} | {st.median(errs):.1f} | {p95:.1f} | {big} | {st.median(rad):+.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
