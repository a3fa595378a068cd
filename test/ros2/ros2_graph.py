# SPDX-License-Identifier: Apache-2.0
"""A default ROS 2 Jazzy node (rclpy on Fast DDS) in a namespace of its own,
watching what tinyline tells the ROS 2 graph, one line per fact:

  ros2_graph.py [--node NS/NAME ...] [--pub NODE=TOPIC ...] [--sub NODE=TOPIC ...]
                [--owner TOPIC=NODE ...] [--log NAME=TEXT ...] [--param NODE=NAME ...]
                [--frame PARENT=CHILD ...] [--timeout S]

  NODE /ns/name                 a node rclpy's graph shows (get_node_names_and_namespaces)
  PUB|SUB /ns/name topic type   its endpoints (get_*_names_and_types_by_node)
  OWNER topic /ns/name          who rclpy says publishes the topic (get_publishers_info_by_topic)
  LOG level name msg            a record on /rosout (rcl's QoS: reliable, transient local, depth 1000)
  PARAM node name value         a declared parameter on /parameter_events
  FRAME parent child x y z qx qy qz qw   a transform on /tf_static (needs tf2_msgs on PYTHONPATH)

Exits 0 ("ALL SEEN") once every expectation holds, 1 at the deadline
("MISSING ..." for each that does not).
"""
import argparse
import sys
import time

import rclpy
from rclpy.qos import QoSDurabilityPolicy, QoSHistoryPolicy, QoSProfile, QoSReliabilityPolicy

from rcl_interfaces.msg import Log, ParameterEvent


def latched(depth):
    return QoSProfile(history=QoSHistoryPolicy.KEEP_LAST, depth=depth, reliability=QoSReliabilityPolicy.RELIABLE,
                      durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)


def pairs(values):
    return [tuple(v.split("=", 1)) for v in values]


def value_text(v):
    fields = {1: "bool_value", 2: "integer_value", 3: "double_value", 4: "string_value", 6: "bool_array_value",
              7: "integer_array_value", 8: "double_array_value", 9: "string_array_value"}
    return repr(getattr(v, fields[v.type])) if v.type in fields else "?"


class Watcher:
    def __init__(self, a):
        self.a = a
        self.node = rclpy.create_node("graph_watcher", namespace="/ros2_side")
        self.facts = set()
        self.node.create_subscription(Log, "/rosout", self.on_log, latched(1000))
        self.node.create_subscription(ParameterEvent, "/parameter_events", self.on_params, QoSProfile(
            history=QoSHistoryPolicy.KEEP_LAST, depth=1000, reliability=QoSReliabilityPolicy.RELIABLE))
        if a.frame:
            from tf2_msgs.msg import TFMessage  # the interface package the test built
            self.node.create_subscription(TFMessage, "/tf_static", self.on_tf, latched(100))

    def fact(self, *parts):
        line = " ".join(str(p) for p in parts)
        if line not in self.facts:
            self.facts.add(line)
            print(line, flush=True)

    def on_log(self, m):
        if m.name != "ros2_side.graph_watcher":
            self.fact("LOG", m.level, m.name, m.msg.replace("\n", " "))

    def on_params(self, m):
        for p in m.new_parameters + m.changed_parameters:
            self.fact("PARAM", m.node, p.name, value_text(p.value))

    def on_tf(self, m):
        for t in m.transforms:
            tr, q = t.transform.translation, t.transform.rotation
            self.fact("FRAME", t.header.frame_id, t.child_frame_id,
                      *(f"{x:.6g}" for x in (tr.x, tr.y, tr.z, q.x, q.y, q.z, q.w)))

    def look_at_graph(self):
        for name, ns in self.node.get_node_names_and_namespaces():
            full = (ns.rstrip("/") + "/" + name)
            self.fact("NODE", full)
            if full.startswith("/ros2_side/"):
                continue
            for topic, types in self.node.get_publisher_names_and_types_by_node(name, ns):
                self.fact("PUB", full, topic, ",".join(types))
            for topic, types in self.node.get_subscriber_names_and_types_by_node(name, ns):
                self.fact("SUB", full, topic, ",".join(types))
        for topic, _ in self.a_owner_topics():
            for info in self.node.get_publishers_info_by_topic(topic):
                self.fact("OWNER", topic, info.node_namespace.rstrip("/") + "/" + info.node_name)

    def a_owner_topics(self):
        return pairs(self.a.owner)

    def missing(self):
        a, f = self.a, self.facts
        out = [f"NODE {n}" for n in a.node if f"NODE {n}" not in f]
        out += [f"PUB {n} {t}" for n, t in pairs(a.pub) if not any(x.startswith(f"PUB {n} {t} ") for x in f)]
        out += [f"SUB {n} {t}" for n, t in pairs(a.sub) if not any(x.startswith(f"SUB {n} {t} ") for x in f)]
        out += [f"OWNER {t} {n}" for t, n in pairs(a.owner) if f"OWNER {t} {n}" not in f]
        out += [f"LOG {n} ...{t}..." for n, t in pairs(a.log)
                if not any(x.startswith("LOG ") and x.split(" ", 3)[2] == n and t in x for x in f)]
        out += [f"PARAM {n} {p}" for n, p in pairs(a.param) if not any(x.startswith(f"PARAM {n} {p} ") for x in f)]
        out += [f"FRAME {p} {c}" for p, c in pairs(a.frame) if not any(x.startswith(f"FRAME {p} {c} ") for x in f)]
        return out

    def run(self):
        deadline = time.monotonic() + self.a.timeout
        next_look = 0.0
        while time.monotonic() < deadline:
            rclpy.spin_once(self.node, timeout_sec=0.05)
            if time.monotonic() >= next_look:
                self.look_at_graph()
                next_look = time.monotonic() + 0.25
                if not self.missing():
                    print("ALL SEEN", flush=True)
                    return 0
        for m in self.missing():
            print("MISSING", m, flush=True)
        return 1


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    for opt in ("node", "pub", "sub", "owner", "log", "param", "frame"):
        ap.add_argument("--" + opt, action="append", default=[])
    ap.add_argument("--timeout", type=float, default=60.0)
    a = ap.parse_args()
    rclpy.init()
    try:
        return Watcher(a).run()
    finally:
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
