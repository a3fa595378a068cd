# SPDX-License-Identifier: Apache-2.0
"""Compares tinyline's type hashes with the ones ROS 2 ships.

  type_hashes.py OURS SHARE [SHARE...] [--require PKG ...]

OURS has one "pkg/msg/Type RIHS01_..." line per type tinyline generates (the
C++ TypeSupport's hash). Each SHARE is a ROS 2 install's share folder, where
rosidl put share/<pkg>/msg/<Type>.json with the type description and its
hash_string. Prints "OK <type>", "DIFFERENT <type> ours <hash> ros2 <hash>"
(then the first field where the descriptions differ, from msggen's own
description) or "NO REFERENCE <type>"; a type of a --require'd package
without a reference, or any difference, fails.
"""
import argparse
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "msg", "gen"))
import msggen  # noqa: E402  the generator's own type description, to say what differs


def reference(shares, full_name):
    pkg, _, name = full_name.split("/")
    for share in shares:
        path = os.path.join(share, pkg, "msg", name + ".json")
        if os.path.exists(path):
            with open(path, encoding="utf-8") as f:
                return json.load(f)
    return None


def our_description(full_name):
    msg_dir = os.path.join(HERE, "..", "..", "msg", "msg")
    msgs = []
    for pkg in sorted(os.listdir(msg_dir)):
        for f in sorted(os.listdir(os.path.join(msg_dir, pkg))):
            if f.endswith(".msg"):
                msgs.append(msggen.parse_msg(os.path.join(msg_dir, pkg, f), pkg))
    all_msgs = {m.full_name.replace("/msg/", "/"): m for m in msgs}
    return msggen.type_description(all_msgs[full_name.replace("/msg/", "/")], all_msgs)


def first_difference(ours, theirs):
    def strip(d):  # the hash leaves default values out
        return {"type_description": {"type_name": d["type_description"]["type_name"],
                                     "fields": [{"name": f["name"], "type": f["type"]} for f in d["type_description"]["fields"]]},
                "referenced_type_descriptions": [
                    {"type_name": r["type_name"], "fields": [{"name": f["name"], "type": f["type"]} for f in r["fields"]]}
                    for r in d["referenced_type_descriptions"]]}
    a, b = json.dumps(strip(ours), indent=1).splitlines(), json.dumps(strip(theirs), indent=1).splitlines()
    for k, (x, y) in enumerate(zip(a, b)):
        if x != y:
            return f"line {k}: ours {x.strip()} / ros2 {y.strip()}"
    return f"{len(a)} lines / {len(b)} lines"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("ours")
    ap.add_argument("shares", nargs="+")
    ap.add_argument("--require", nargs="*", default=[])
    a = ap.parse_args()
    failed = 0
    with open(a.ours, encoding="utf-8") as f:
        rows = [line.split() for line in f if line.strip()]
    for full_name, ours in rows:
        ref = reference(a.shares, full_name)
        if ref is None:
            print("NO REFERENCE", full_name)
            failed += full_name.split("/")[0] in a.require
            continue
        theirs = ref["type_hashes"][0]["hash_string"]
        if ours == theirs:
            print("OK", full_name, ours)
        else:
            print("DIFFERENT", full_name, "ours", ours, "ros2", theirs)
            print("  ", first_difference(our_description(full_name), ref["type_description_msg"]))
            failed += 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
