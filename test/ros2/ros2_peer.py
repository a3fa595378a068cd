# SPDX-License-Identifier: Apache-2.0
"""A real ROS 2 Jazzy node (rclpy on Fast DDS, default settings) for the
interop tests: it publishes, subscribes and round-trips messages of the
standard types tinyline mirrors (and tinyline_msgs/LineScan, from the
interface package built with rosidl), and reports what it sees, one line per
fact.

  ros2_peer.py roundtrip --type T --out /in --back /out --count N
      publishes message i on OUT and expects it back, field for field, on BACK
      (a tinyline process relays OUT to BACK through its own C++ types): probes
      (i = 0) until the first one comes back, then i = 1..N; prints
      "ROUNDTRIP OK N" or the first difference
  ros2_peer.py pub --type T --topic X --count N [--qos Q] [--wait-subs K] [--go-file F] [--period S] [--linger S]
      once K subscriptions matched (and file F exists: the other side says it
      matched this publisher too), publishes i = 1..N ("SENT i"), then stays
      alive for S seconds (a latched publisher must outlive its late joiners)
  ros2_peer.py sub --type T --topic X --count N [--qos Q] [--any]
      prints "READY" once a publisher matched, then "GOT i ok" (or "GOT i
      MISMATCH <difference>") per message; exits 0 after N messages. With
      --any, messages of any origin: "HEARD <summary>" each
  ros2_peer.py endpoints --topic X --count N
      waits until N endpoints of X are known, prints each as
      "ENDPOINT pub|sub <type> <type hash> <reliability> <durability>"

QoS Q: reliable (the default profile; --depth, 10), sensor_data (best
effort), latched (reliable, transient local, depth 1). Every message carries its index i (in
the stamp, the text or the first marker's id) and is made by make(T, i), so
the receiver checks every field. Incompatible QoS events print "INCOMPATIBLE
<policy>". Everything runs under one deadline (--timeout, 60 s).
"""
import argparse
import os
import sys
import time

import rclpy
from rclpy.qos import (QoSDurabilityPolicy, QoSHistoryPolicy, QoSProfile, QoSReliabilityPolicy,
                       qos_profile_sensor_data)
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.serialization import deserialize_message, serialize_message

from builtin_interfaces.msg import Duration, Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Pose, Quaternion, Vector3
from sensor_msgs.msg import CompressedImage, LaserScan, PointCloud2, PointField
from std_msgs.msg import ColorRGBA, Header, String
from visualization_msgs.msg import Marker, MarkerArray, MeshFile, UVCoordinate

BASE_SEC = 1700000000


def header(i, frame):
    return Header(stamp=Time(sec=BASE_SEC + i, nanosec=123456789 + i), frame_id=frame)


def make_string(i):
    return String(data=f"tinyline interop {i}: grüße")


def make_laser_scan(i):
    ranges = [0.05 + k / 128.0 + i / 1024.0 for k in range(256)]
    ranges[7] = float("inf")  # out of range, as ROS encodes it
    return LaserScan(header=header(i, "laser"), angle_min=-0.609375, angle_max=0.609375,
                     angle_increment=1.21875 / 256, time_increment=0.0, scan_time=1 / 64,
                     range_min=0.05, range_max=2.0, ranges=ranges,
                     intensities=[float((k * 37 + i) % 1000) for k in range(256)])


def make_point_cloud2(i):
    fields = [PointField(name=n, offset=4 * k, datatype=PointField.FLOAT32, count=1)
              for k, n in enumerate(["x", "y", "z", "intensity"])]
    width = 64 + i
    data = bytes((k * 7 + i) % 256 for k in range(16 * width))
    return PointCloud2(header=header(i, "cloud"), height=1, width=width, fields=fields, is_bigendian=False,
                       point_step=16, row_step=16 * width, data=data, is_dense=(i % 2 == 0))


def make_diagnostic_array(i):
    statuses = [DiagnosticStatus(level=bytes([k % 4]), name=f"/laser/driver {k}", message=f"status {i}.{k}",
                                 hardware_id=f"tiny-{i}",
                                 values=[KeyValue(key=f"k{j}", value=f"{i * j}") for j in range(k + 1)])
                for k in range(3)]
    return DiagnosticArray(header=header(i, ""), status=statuses)


def make_marker_array(i):
    markers = []
    for k in range(2):
        m = Marker(header=header(i, "map"), ns="tinyline", id=i if k == 0 else 1000 + k, type=Marker.SPHERE_LIST,
                   action=Marker.ADD,
                   pose=Pose(position=Point(x=0.5 * i, y=-1.25, z=float(k)), orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)),
                   scale=Vector3(x=0.1, y=0.2, z=0.3), color=ColorRGBA(r=1.0, g=0.5, b=0.25, a=1.0),
                   lifetime=Duration(sec=2, nanosec=500), frame_locked=(k == 1),
                   points=[Point(x=float(p), y=float(-p), z=0.125 * p) for p in range(4)],
                   colors=[ColorRGBA(r=0.0, g=1.0, b=0.0, a=0.5) for _ in range(4)],
                   texture_resource="", texture=CompressedImage(header=header(i, "tex"), format="png", data=bytes(range(5))),
                   uv_coordinates=[UVCoordinate(u=0.25, v=0.75)], text=f"tomato {i}",
                   mesh_resource="", mesh_file=MeshFile(filename="a.stl", data=bytes([1, 2, 3])),
                   mesh_use_embedded_materials=False)
        markers.append(m)
    return MarkerArray(markers=markers)


def make_line_scan(i):
    from tinyline_msgs.msg import LineScan  # built from msg/ros2/tinyline_msgs (PYTHONPATH)
    n = 256
    return LineScan(header=header(i, "laser"), set_index=i, temperature_c=44.5,
                    angles=[-0.609375 + k / 210.0 for k in range(n)], distance_m=[0.05 + k / 128.0 for k in range(n)],
                    intensity=[float(k % 50) for k in range(n)], reflectance=[0.25] * n,
                    pulses=[(20, 100, 200, 400, 700)[k % 5] for k in range(n)],
                    status=[LineScan.STATUS_VALID if k % 9 else LineScan.STATUS_SATURATED for k in range(n)])


def line_scan_type():
    from tinyline_msgs.msg import LineScan
    return LineScan


TYPES = {
    "string": (String, make_string, lambda m: int(m.data.split()[2].rstrip(":"))),
    "laser_scan": (LaserScan, make_laser_scan, lambda m: m.header.stamp.sec - BASE_SEC),
    "point_cloud2": (PointCloud2, make_point_cloud2, lambda m: m.header.stamp.sec - BASE_SEC),
    "diagnostic_array": (DiagnosticArray, make_diagnostic_array, lambda m: m.header.stamp.sec - BASE_SEC),
    "marker_array": (MarkerArray, make_marker_array, lambda m: m.markers[0].id),
    "line_scan": (line_scan_type, make_line_scan, lambda m: m.set_index),
}


def qos(name, depth):
    if name == "sensor_data":
        return qos_profile_sensor_data
    if name == "latched":
        return QoSProfile(history=QoSHistoryPolicy.KEEP_LAST, depth=1, reliability=QoSReliabilityPolicy.RELIABLE,
                          durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
    return QoSProfile(history=QoSHistoryPolicy.KEEP_LAST, depth=depth, reliability=QoSReliabilityPolicy.RELIABLE,
                      durability=QoSDurabilityPolicy.VOLATILE)


def difference(a, b, path=""):
    """The first field where two messages differ, as 'path: a != b'."""
    if hasattr(a, "get_fields_and_field_types"):
        for f in a.get_fields_and_field_types():
            d = difference(getattr(a, f), getattr(b, f), f"{path}.{f}" if path else f)
            if d:
                return d
        return ""
    if isinstance(a, (list, tuple)) or hasattr(a, "tolist"):
        a, b = list(a), list(b)
        if len(a) != len(b):
            return f"{path}: {len(a)} elements != {len(b)}"
        for k, (x, y) in enumerate(zip(a, b)):
            d = difference(x, y, f"{path}[{k}]")
            if d:
                return d
        return ""
    return "" if a == b else f"{path}: {a!r} != {b!r}"


def summary(msg):
    if isinstance(msg, String):
        return msg.data
    if isinstance(msg, LaserScan):
        finite = [r for r in msg.ranges if msg.range_min <= r <= msg.range_max]
        return (f"frame={msg.header.frame_id} ranges={len(msg.ranges)} in_range={len(finite)} "
                f"angles={msg.angle_min:.4f}..{msg.angle_max:.4f} limits={msg.range_min:.3f}..{msg.range_max:.3f}")
    if isinstance(msg, PointCloud2):
        import math
        import struct
        points = [struct.unpack_from("<ffff" if not msg.is_bigendian else ">ffff", bytes(msg.data), k * msg.point_step)
                  for k in range(msg.width * msg.height)]
        valid = [p for p in points if not math.isnan(p[0])]
        fields = ",".join(f"{f.name}:{f.offset}:{f.datatype}:{f.count}" for f in msg.fields)
        return (f"frame={msg.header.frame_id} height={msg.height} width={msg.width} fields={fields} "
                f"point_step={msg.point_step} row_step={msg.row_step} dense={msg.is_dense} valid={len(valid)} "
                f"z_max={max((p[2] for p in valid), default=0):.3f}")
    return type(msg).__name__


def say(*parts):
    print(*parts, flush=True)


class Peer:
    def __init__(self, args):
        self.args = args
        self.deadline = time.monotonic() + args.timeout
        rclpy.init()
        self.node = rclpy.create_node("ros2_peer")
        self.msg_type, self.make, self.index = TYPES[args.type]
        if not hasattr(self.msg_type, "get_fields_and_field_types"):
            self.msg_type = self.msg_type()  # a type that needs its package imported first

    def spin_until(self, done, step=0.05):
        while not done() and time.monotonic() < self.deadline:
            rclpy.spin_once(self.node, timeout_sec=step)
        return done()

    def incompatible(self, event):
        say("INCOMPATIBLE", event.last_policy_kind.name.replace("RMW_QOS_POLICY_", ""))

    def publisher(self, topic, profile):
        return self.node.create_publisher(self.msg_type, topic, qos(profile, self.args.depth),
                                          event_callbacks=PublisherEventCallbacks(incompatible_qos=self.incompatible))

    def subscription(self, topic, profile, callback):
        return self.node.create_subscription(self.msg_type, topic, callback, qos(profile, self.args.depth),
                                             event_callbacks=SubscriptionEventCallbacks(incompatible_qos=self.incompatible))

    def check(self, msg):
        """Compares with make(i) as rclpy itself carries it (float32 fields rounded)."""
        i = self.index(msg)
        expected = deserialize_message(serialize_message(self.make(i)), self.msg_type)
        return i, difference(expected, msg)


def roundtrip(p, a):
    back = []
    p.subscription(a.back, a.qos, back.append)
    pub = p.publisher(a.out, a.qos)
    probe = p.make(0)

    def probe_came_back():
        pub.publish(probe)
        return any(p.index(m) == 0 for m in back)
    if not p.spin_until(probe_came_back, step=0.2):
        say("NO ROUNDTRIP: nothing came back on", a.back, f"(subscriptions {pub.get_subscription_count()})")
        return 1
    say("PATH UP")
    for i in range(1, a.count + 1):
        pub.publish(p.make(i))
    p.spin_until(lambda: sum(1 for m in back if p.index(m) > 0) >= a.count)
    got = [m for m in back if p.index(m) > 0]
    if [p.index(m) for m in got] != list(range(1, a.count + 1)):
        say("ROUNDTRIP ORDER", [p.index(m) for m in got])
        return 1
    for m in got:
        i, d = p.check(m)
        if d:
            say("ROUNDTRIP MISMATCH", i, d)
            return 1
    say("ROUNDTRIP OK", len(got))
    return 0


def publish(p, a):
    pub = p.publisher(a.topic, a.qos)
    if not p.spin_until(lambda: pub.get_subscription_count() >= a.wait_subs):
        say("NO SUBSCRIBER")
        return 1
    say("MATCHED", pub.get_subscription_count())
    if a.go_file and not p.spin_until(lambda: os.path.exists(a.go_file)):
        say("NO GO")
        return 1
    for i in range(1, a.count + 1):
        pub.publish(p.make(i))
        say("SENT", i)
        if a.period > 0:
            p.spin_until(lambda t=time.monotonic() + a.period: time.monotonic() >= t, step=min(a.period, 0.05))
    say("DONE")
    end = time.monotonic() + a.linger
    p.spin_until(lambda: time.monotonic() >= end, step=0.1)
    return 0


def subscribe(p, a):
    got = []

    def on(msg):
        if a.any:
            got.append(msg)
            say("HEARD", summary(msg))
            return
        i, d = p.check(msg)
        got.append(i)
        say("GOT", i, "ok" if not d else "MISMATCH " + d)
    sub = p.subscription(a.topic, a.qos, on)
    p.spin_until(lambda: sub.get_publisher_count() > 0)
    say("READY", sub.get_publisher_count())
    p.spin_until(lambda: len(got) >= a.count)
    return 0 if len(got) >= a.count else 1


def endpoints(p, a):
    def seen():
        return (p.node.get_publishers_info_by_topic(a.topic) + p.node.get_subscriptions_info_by_topic(a.topic))
    p.spin_until(lambda: len(seen()) >= a.count)
    for e in seen():
        kind = "pub" if e.endpoint_type.name == "PUBLISHER" else "sub"
        say("ENDPOINT", kind, e.topic_type, str(e.topic_type_hash), e.qos_profile.reliability.name,
            e.qos_profile.durability.name)
    return 0 if len(seen()) >= a.count else 1


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mode", choices=["roundtrip", "pub", "sub", "endpoints"])
    ap.add_argument("--type", choices=sorted(TYPES), default="string")
    ap.add_argument("--topic", default="/chatter")
    ap.add_argument("--out", default="/ros2/in")
    ap.add_argument("--back", default="/ros2/out")
    ap.add_argument("--count", type=int, default=5)
    ap.add_argument("--qos", choices=["reliable", "sensor_data", "latched"], default="reliable")
    ap.add_argument("--wait-subs", type=int, default=1)
    ap.add_argument("--period", type=float, default=0.0)
    ap.add_argument("--linger", type=float, default=0.0)
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--any", action="store_true")
    ap.add_argument("--depth", type=int, default=10)
    ap.add_argument("--go-file", default="")
    a = ap.parse_args()
    p = Peer(a)
    run = {"roundtrip": roundtrip, "pub": publish, "sub": subscribe, "endpoints": endpoints}[a.mode]
    try:
        return run(p, a)
    finally:
        p.node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
