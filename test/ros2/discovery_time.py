# SPDX-License-Identifier: Apache-2.0
"""How long a late joiner takes to hear a running publisher, tinyline and
ROS 2 (rclpy on Fast DDS) in every pairing, both on their default settings.
Run it in a namespace with a network card, as the tests do:

  test/ros2/in_netns.sh .venv/bin/python test/ros2/discovery_time.py build/tools/tinyline [TRIALS]

For each pairing and each order (the subscriber or the publisher starting
second) it starts the first process, waits until it runs, then starts the
second and times from that start to the subscriber's first message. The time
includes starting the second process (Python and rclpy, or tinyline), so the
ROS 2 - ROS 2 row is the reference.
"""
import os
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
PY = sys.executable


def ros_pub(topic):
    return [PY, os.path.join(HERE, "ros2_peer.py"), "pub", "--topic", topic, "--count", "1000000", "--period", "0.02",
            "--wait-subs", "0", "--timeout", "600"]


def ros_sub(topic):
    return [PY, os.path.join(HERE, "ros2_peer.py"), "sub", "--topic", topic, "--count", "1", "--any", "--timeout", "60"]


def tl_pub(tl, topic):
    return [tl, "run", "tinyline", "pulse", "--dds", "-p", "rate_hz:=50", "-r", f"output:={topic}", "--no-table"]


def tl_sub(tl, topic):
    return [tl, "run", "tinyline", "echo", "--dds", "-r", f"input:={topic}", "--no-table"]


def first_line(proc, prefixes, deadline):
    for line in proc.stdout:
        if any(line.startswith(p) for p in prefixes):
            return True
        if time.monotonic() > deadline:
            return False
    return False


HEARD = ("HEARD", "data:")


def trial(pub_cmd, sub_cmd, subscriber_second):
    first_cmd, second_cmd = (pub_cmd, sub_cmd) if subscriber_second else (sub_cmd, pub_cmd)
    opts = dict(stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    first = subprocess.Popen(first_cmd, **opts)
    try:
        time.sleep(2.0)  # the first process is up and running: its start-up is not measured
        t0 = time.monotonic()
        second = subprocess.Popen(second_cmd, **opts)
        try:
            listener = second if subscriber_second else first
            ok = first_line(listener, HEARD, t0 + 60)
            return time.monotonic() - t0 if ok else float("nan")
        finally:
            second.kill()
            second.wait()
    finally:
        first.kill()
        first.wait()


def main():
    tl = os.path.abspath(sys.argv[1])
    trials = int(sys.argv[2]) if len(sys.argv) > 2 else 10
    pairs = [("ROS 2", "ROS 2", ros_pub, ros_sub), ("tinyline", "ROS 2", lambda t: tl_pub(tl, t), ros_sub),
             ("ROS 2", "tinyline", ros_pub, lambda t: tl_sub(tl, t)),
             ("tinyline", "tinyline", lambda t: tl_pub(tl, t), lambda t: tl_sub(tl, t))]
    print(f"{'publisher':10} {'subscriber':10} {'starts second':13} {'median s':>9} {'max s':>7} {'heard':>6}")
    n = 0
    for pub_name, sub_name, pub, sub in pairs:
        for subscriber_second in (True, False):
            times = []
            for _ in range(trials):
                n += 1
                topic = f"/discovery_time_{n}"
                times.append(trial(pub(topic), sub(topic), subscriber_second))
            ok = [t for t in times if t == t]
            second = "subscriber" if subscriber_second else "publisher"
            med = statistics.median(ok) if ok else float("nan")
            print(f"{pub_name:10} {sub_name:10} {second:13} {med:9.2f} {max(ok) if ok else float('nan'):7.2f} "
                  f"{len(ok):3}/{trials}", flush=True)


if __name__ == "__main__":
    main()
