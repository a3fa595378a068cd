#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Writes the organised clouds a camera published (sensor_msgs/PointCloud2,
XYZ + packed RGB, recorded in an MCAP file) as a folder of RGB-D frames in
the layout RGB-D data sets use: rgb/NNNNNN.png (8-bit colour), depth/NNNNNN.png
(16-bit depth, 0 = none) and intrinsics.yaml. Decoding by the mcap packages,
images by numpy + Pillow: independent of tinyline's own readers and writers.

usage: write_frames.py BAG.mcap OUT_DIR --fx FX --fy FY --cx CX --cy CY
                       [--topic /camera/points] [--depth-scale 1000]
"""
import argparse
import os
import sys

import numpy as np
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from PIL import Image


def clouds(path, topic):
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _schema, _channel, _message, m in reader.iter_decoded_messages(topics=[topic]):
            yield m


def field_offsets(m):
    offsets = {f.name: f.offset for f in m.fields}
    for name in ("x", "y", "z", "rgb"):
        if name not in offsets:
            sys.exit(f"cloud has no field {name!r} (fields: {sorted(offsets)})")
    return offsets


def decode(m):
    """(H x W x 3 float32 xyz, H x W x 3 uint8 rgb) of an organised cloud."""
    if m.height < 2:
        sys.exit("cloud is not organised (height 1): it has no image layout")
    o = field_offsets(m)
    raw = np.frombuffer(bytes(m.data), dtype=np.uint8).reshape(m.height, m.width, m.point_step)
    xyz = np.stack([raw[:, :, o[k]:o[k] + 4].copy().view("<f4")[:, :, 0] for k in ("x", "y", "z")], axis=-1)
    packed = raw[:, :, o["rgb"]:o["rgb"] + 4].copy().view("<u4")[:, :, 0]
    rgb = np.stack([(packed >> 16) & 255, (packed >> 8) & 255, packed & 255], axis=-1).astype(np.uint8)
    return xyz, rgb


def depth_image(z, scale):
    """16-bit depth in 1/scale m; 0 where there is none."""
    d = np.where(np.isfinite(z) & (z > 0), np.rint(np.nan_to_num(z) * scale), 0)
    if d.max(initial=0) > 65535:
        sys.exit(f"depth {d.max() / scale:.2f} m does not fit 16 bits at depth_scale {scale}")
    return d.astype(np.uint16)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("bag")
    ap.add_argument("out")
    for k in ("fx", "fy", "cx", "cy"):
        ap.add_argument("--" + k, type=float, required=True)
    ap.add_argument("--topic", default="/camera/points")
    ap.add_argument("--depth-scale", type=float, default=1000.0)
    a = ap.parse_args()
    os.makedirs(os.path.join(a.out, "rgb"), exist_ok=True)
    os.makedirs(os.path.join(a.out, "depth"), exist_ok=True)
    n, size = 0, None
    for m in clouds(a.bag, a.topic):
        xyz, rgb = decode(m)
        size = (m.width, m.height)
        name = f"{n:06d}.png"
        Image.fromarray(rgb).save(os.path.join(a.out, "rgb", name))
        depth = Image.fromarray(depth_image(xyz[:, :, 2], a.depth_scale))
        assert depth.mode == "I;16", depth.mode
        depth.save(os.path.join(a.out, "depth", name))
        n += 1
    if n == 0:
        sys.exit(f"no message on {a.topic} in {a.bag}")
    with open(os.path.join(a.out, "intrinsics.yaml"), "w") as f:
        f.write(f"width: {size[0]}\nheight: {size[1]}\nfx: {a.fx!r}\nfy: {a.fy!r}\ncx: {a.cx!r}\ncy: {a.cy!r}\n"
                f"depth_scale: {a.depth_scale!r}\n")
    print(f"{n} frame(s) of {size[0]} x {size[1]} px written to {a.out}")


if __name__ == "__main__":
    main()
