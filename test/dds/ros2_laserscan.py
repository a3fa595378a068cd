# SPDX-License-Identifier: Apache-2.0
"""An independent DDS implementation (the cyclonedds package from PyPI, its own
bundled Cyclone DDS and CDR code) talking to tinyline with types named the way
ROS 2 names them.

  python ros2_laserscan.py sub TOPIC N [best_effort]
                                         print N LaserScans received on DDS topic rt/TOPIC
                                         (reliable as ROS 2's default profile, or best effort as
                                         its SensorDataQoS)
  python ros2_laserscan.py pub TOPIC N   publish N LaserScans once a reader matched

Each scan is one line: "SCAN|<sec>|<nanosec>|<frame_id>|<9 float fields>|<ranges>|<intensities>"
with floats printed as %.9g, so the C++ side can compare exactly.
DDS settings come from ROS_DOMAIN_ID and CYCLONEDDS_URI, as for every tinyline process.
"""
import os
import struct
import sys
import time
from dataclasses import dataclass

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import float32, int32, sequence, uint32
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


@dataclass
class LaserScan(IdlStruct, typename="sensor_msgs::msg::dds_::LaserScan_"):
    header: Header
    angle_min: float32
    angle_max: float32
    angle_increment: float32
    time_increment: float32
    scan_time: float32
    range_min: float32
    range_max: float32
    ranges: sequence[float32]
    intensities: sequence[float32]


FLOATS = ["angle_min", "angle_max", "angle_increment", "time_increment", "scan_time", "range_min", "range_max"]


def line(s):
    f = lambda x: "%.9g" % struct.unpack("<f", struct.pack("<f", x))[0]  # as float32 carries it
    return "SCAN|%d|%d|%s|%s|%s|%s" % (
        s.header.stamp.sec, s.header.stamp.nanosec, s.header.frame_id,
        ",".join(f(getattr(s, n)) for n in FLOATS),
        ",".join(f(x) for x in s.ranges), ",".join(f(x) for x in s.intensities))


def main():
    mode, topic, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
    dp = DomainParticipant(int(os.environ.get("ROS_DOMAIN_ID", "0")))
    t = Topic(dp, "rt/" + topic.lstrip("/"), LaserScan)
    best_effort = len(sys.argv) > 4 and sys.argv[4] == "best_effort"
    reliability = Policy.Reliability.BestEffort if best_effort else Policy.Reliability.Reliable(duration(seconds=1))
    qos = Qos(reliability, Policy.History.KeepLast(50), Policy.DataRepresentation(use_cdrv0_representation=True))
    deadline = time.monotonic() + 30
    if mode == "sub":
        reader = DataReader(dp, t, qos=qos)
        # Ready once this reader knows the writer: a best-effort reader drops
        # data from a writer it has not discovered yet (nothing is resent).
        while not reader.get_matched_publications() and time.monotonic() < deadline:
            time.sleep(0.005)
        print("READY", flush=True)
        got = 0
        while got < n and time.monotonic() < deadline:
            for s in reader.take(N=10):
                print(line(s), flush=True)
                got += 1
            time.sleep(0.005)  # a helper polling its reader, with a deadline
        return 0 if got >= n else 1
    writer = DataWriter(dp, t, qos=qos)
    while not writer.get_matched_subscriptions() and time.monotonic() < deadline:
        time.sleep(0.005)
    if not writer.get_matched_subscriptions():
        print("no reader matched", flush=True)
        return 1
    for i in range(n):
        s = LaserScan(
            header=Header(stamp=Time(sec=1700000000 + i, nanosec=250000000 + i), frame_id="py_laser"),
            angle_min=-0.5, angle_max=0.5, angle_increment=1.0 / 255, time_increment=1e-5, scan_time=0.01,
            range_min=0.05, range_max=2.0,
            ranges=[0.05 + 0.001 * k + 0.01 * i for k in range(256)],
            intensities=[float(k % 7) for k in range(256)])
        writer.write(s)
        print("SENT" + line(s)[4:], flush=True)
    # Reliable: exit only once the reader acknowledged everything.
    writer.wait_for_acks(duration(seconds=10))
    return 0


if __name__ == "__main__":
    sys.exit(main())
