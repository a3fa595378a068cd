# SPDX-License-Identifier: Apache-2.0
"""CDR interop with rosbags, an independent CDR implementation.

usage: rosbags_interop.py MSG_DIR WORK_DIR

1. Every standard type we mirror is, field for field (names, types, array
   shapes, constants), the ROS 2 Jazzy definition rosbags ships.
2. Every WORK_DIR/<pkg>__<Type>__<n>.cdr that tinyline serialized decodes with
   rosbags to exactly the values in the matching .json that tinyline dumped.
3. The reverse: rosbags serializes the same values; the bytes must equal
   tinyline's, and are written to <name>.rosbags.cdr for tinyline to decode.
"""
import json
import pathlib
import sys

import numpy as np
from rosbags.typesys import Stores, get_typestore, get_types_from_msg
from rosbags.typesys.base import Nodetype

msg_dir = pathlib.Path(sys.argv[1])
work = pathlib.Path(sys.argv[2])
store = get_typestore(Stores.ROS2_JAZZY)

ours = {}
for f in sorted(msg_dir.glob("*/*.msg")):
    ours.update(get_types_from_msg(f.read_text(), f"{f.parent.name}/msg/{f.stem}"))

failures = []
mirrored = 0
for name, (consts, fields) in sorted(ours.items()):
    if name.startswith("tinyline_msgs/"):
        continue
    ref = store.fielddefs.get(name)
    if ref is None:
        failures.append(f"{name}: not a ROS 2 Jazzy type")
        continue
    if sorted(consts) != sorted(ref[0]):
        failures.append(f"{name}: constants differ: ours {consts} vs ROS 2 {ref[0]}")
    if list(fields) != list(ref[1]):
        failures.append(f"{name}: fields differ:\n  ours {fields}\n  ROS2 {ref[1]}")
    mirrored += 1
store.register({k: v for k, v in ours.items() if k.startswith("tinyline_msgs/")})

DTYPES = {"bool": np.bool_, "byte": np.uint8, "char": np.uint8, "int8": np.int8, "uint8": np.uint8,
          "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32,
          "int64": np.int64, "uint64": np.uint64, "float32": np.float32, "float64": np.float64}


# ROS 2 defines `byte` as an unsigned octet (tinyline: uint8); rosbags holds it
# as a signed int8. Same wire byte, different Python value: map between them.
def is_byte(desc):
    return desc[0] == Nodetype.BASE and desc[1][0] == "byte"


def plain(value, desc):
    """A decoded rosbags value as plain Python data (JSON-comparable)."""
    kind, detail = desc
    if kind == Nodetype.BASE:
        return value & 0xFF if is_byte(desc) else value
    if kind == Nodetype.NAME:
        fields = store.fielddefs[detail][1]
        return {fname: plain(getattr(value, fname), fdesc) for fname, fdesc in fields}
    inner, _size = detail
    if inner[0] == Nodetype.BASE and inner[1][0] != "string":
        arr = np.asarray(value)
        return (arr.astype(np.uint8) if is_byte(inner) else arr).tolist()
    return [plain(v, inner) for v in value]


def build(data, desc):
    """Plain data -> a rosbags value of the described type."""
    kind, detail = desc
    if kind == Nodetype.BASE:
        return (data - 256 if data > 127 else data) if is_byte(desc) else data
    if kind == Nodetype.NAME:
        fields = store.fielddefs[detail][1]
        return store.types[detail](**{fname: build(data[fname], fdesc) for fname, fdesc in fields})
    inner, _size = detail
    if inner[0] == Nodetype.BASE and inner[1][0] != "string":
        arr = np.array(data, dtype=np.uint8 if is_byte(inner) else DTYPES[inner[1][0]])
        return arr.astype(np.int8) if is_byte(inner) else arr
    return [build(v, inner) for v in data]


def compare(got, want, path):
    if isinstance(want, dict):
        for k in want:
            compare(got[k], want[k], f"{path}.{k}")
    elif isinstance(want, list):
        if len(got) != len(want):
            failures.append(f"{path}: length {len(got)} != {len(want)}")
            return
        for i, (g, w) in enumerate(zip(got, want)):
            compare(g, w, f"{path}[{i}]")
    elif got != want:
        failures.append(f"{path}: rosbags decoded {got!r}, tinyline wrote {want!r}")


decoded = 0
for cdr in sorted(work.glob("*.cdr")):
    if cdr.name.endswith(".rosbags.cdr"):
        continue
    pkg, typ, _n = cdr.stem.split("__")
    name = f"{pkg}/msg/{typ}"
    want = json.loads(cdr.with_suffix(".json").read_text())
    raw = cdr.read_bytes()
    try:
        msg = store.deserialize_cdr(raw, name)
    except Exception as e:  # noqa: BLE001 - report every failure
        failures.append(f"{cdr.name}: rosbags cannot decode: {e}")
        continue
    compare(plain(msg, (Nodetype.NAME, name)), want, cdr.stem)
    back = bytes(store.serialize_cdr(build(want, (Nodetype.NAME, name)), name))
    if back != raw:
        failures.append(f"{cdr.name}: rosbags serializes {len(back)} bytes that differ from tinyline's {len(raw)}")
    cdr.with_name(cdr.stem + ".rosbags.cdr").write_bytes(back)
    decoded += 1

print(f"mirrored standard types checked: {mirrored}; messages decoded and re-encoded: {decoded}")
for f in failures[:50]:
    print("FAIL", f)
sys.exit(1 if failures or decoded == 0 else 0)
