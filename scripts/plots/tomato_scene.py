#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The harvesting demo's picture: the camera's first view of the truss with
the fitted spheres, expected pedicel directions, pick order, the laser
verification's cuts, each pick's outcome and the harvest's score, read back
from the MCAP the demo recorded (launch/tomato_harvest.launch.yaml).

usage: .venv/bin/python scripts/plots/tomato_scene.py BAG.mcap [--out tomato_harvest.png]
"""
import argparse
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mcap.reader import make_reader  # noqa: E402
from mcap_ros2.decoder import DecoderFactory  # noqa: E402

PICKS = {0: "picked", 1: "cut failure", 2: "cut another's", 3: "left"}


def first_messages(path):
    cloud, tomatoes, verifications, summary, score = None, None, [], None, None
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _schema, channel, _message, m in reader.iter_decoded_messages(
                topics=["/camera/points", "/tomatoes", "/harvest/verification", "/harvest/summary",
                        "/harvest/score"]):
            if channel.topic == "/camera/points" and cloud is None:
                cloud = m
            elif channel.topic == "/tomatoes" and tomatoes is None and len(m.tomatoes) > 0:
                tomatoes = m
            elif channel.topic == "/harvest/verification":
                verifications.append(m)
            elif channel.topic == "/harvest/summary":
                summary = m
            elif channel.topic == "/harvest/score":
                score = m
    return cloud, tomatoes, verifications, summary, score


def decode_cloud(m):
    raw = np.frombuffer(bytes(m.data), dtype=np.uint8).reshape(m.height, m.width, m.point_step)
    xyz = raw[:, :, 0:12].copy().view(np.float32).reshape(m.height, m.width, 3)
    rgb = raw[:, :, 12:16].copy().view(np.uint32).reshape(m.height, m.width)
    img = np.stack([(rgb >> 16) & 255, (rgb >> 8) & 255, rgb & 255], axis=-1).astype(np.uint8)
    return xyz, img


def intrinsics(xyz):
    """Pinhole fx, fy, cx, cy fitted to the organised cloud (u = fx x/z + cx)."""
    h, w, _ = xyz.shape
    v, u = np.mgrid[0:h, 0:w]
    ok = np.isfinite(xyz[:, :, 2]) & (xyz[:, :, 2] > 0)
    a = xyz[:, :, 0][ok] / xyz[:, :, 2][ok]
    b = xyz[:, :, 1][ok] / xyz[:, :, 2][ok]
    fx, cx = np.polyfit(a, u[ok], 1)
    fy, cy = np.polyfit(b, v[ok], 1)
    return fx, fy, cx, cy


RING = {0: "lime", 1: "red", 2: "orange", 3: "white"}


def pick_outcomes(tomatoes, summary):
    """Each detected tomato's pick (outcome, attempts), matched by nearest centre."""
    if tomatoes is None or summary is None:
        return {}
    centres = np.array([[t.centre.x, t.centre.y, t.centre.z] for t in tomatoes.tomatoes])
    out = {}
    for p in summary.picks:
        k = int(np.argmin(np.linalg.norm(centres - [p.centre.x, p.centre.y, p.centre.z], axis=1)))
        out[k] = (p.outcome, p.attempts)
    return out


def draw_tomato(ax, project, fx, t, outcome):
    c = np.array([t.centre.x, t.centre.y, t.centre.z])
    u, v = project(c)
    ring = "yellow" if outcome is None else RING.get(outcome[0], "yellow")
    ax.add_patch(plt.Circle((u, v), fx * t.radius_m / c[2], fill=False, ec=ring, lw=2))
    d = np.array([t.pedicel_direction.x, t.pedicel_direction.y, t.pedicel_direction.z])
    u0, v0 = project(c + t.radius_m * d)
    u1, v1 = project(c + (t.radius_m + 0.04) * d)
    ax.annotate("", xy=(u1, v1), xytext=(u0, v0), arrowprops=dict(arrowstyle="->", color="lime", lw=2))
    ax.text(u, v, f"#{t.pick_rank + 1}", color="white", ha="center", va="center", fontsize=12, weight="bold")
    cu, cv = project([t.cut_point.x, t.cut_point.y, t.cut_point.z])
    ax.plot(cu, cv, "x", color="yellow", ms=8, mew=2)



def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("bag")
    ap.add_argument("--out", default="tomato_harvest.png")
    args = ap.parse_args()
    cloud, tomatoes, verifications, summary, score = first_messages(args.bag)
    if cloud is None:
        sys.exit(f"{args.bag}: no /camera/points message")
    xyz, img = decode_cloud(cloud)
    fx, fy, cx, cy = intrinsics(xyz)

    def project(p):
        return fx * p[0] / p[2] + cx, fy * p[1] / p[2] + cy

    fig, ax = plt.subplots(figsize=(9, 7))
    ax.imshow(img)
    ax.set_axis_off()
    title = "simulated truss"
    outcome_of = pick_outcomes(tomatoes, summary)
    if tomatoes is not None:
        title = f"{len(tomatoes.tomatoes)} tomatoes, pick order {list(tomatoes.pick_order)}"
        for k, t in enumerate(tomatoes.tomatoes):
            draw_tomato(ax, project, fx, t, outcome_of.get(k))
    for m in verifications:
        cut = [m.cut_point.x, m.cut_point.y, m.cut_point.z]
        if not (np.all(np.isfinite(cut)) and cut[2] > 0):
            continue  # nothing found: no cut point to draw
        cu, cv = project(cut)
        colour = "cyan" if m.outcome in (0, 1) else "magenta"
        ax.plot(cu, cv, "o", mfc="none", mec=colour, ms=10, mew=2)
    if outcome_of:
        lines = [f"#{tomatoes.tomatoes[k].pick_rank + 1}: {PICKS.get(o, '?')} (attempts {a})"
                 for k, (o, a) in sorted(outcome_of.items(), key=lambda kv: tomatoes.tomatoes[kv[0]].pick_rank)]
        ax.text(0.01, 0.99, "\n".join(lines), transform=ax.transAxes, va="top", fontsize=10, family="monospace",
                bbox=dict(facecolor="white", alpha=0.85, edgecolor="grey"))
    if score is not None:
        title += (f"\nclass {score.truss_class} seed {score.seed}: trials {score.trials}, SD {score.detected}, "
                  f"SP(1) {score.picked_first}, SP(2) {score.picked_second}, HS {score.human}, CF {score.cut_failures}")
    ax.set_title(title + "\nspheres coloured by outcome (green picked, red cut failure, orange cut another's, white left); "
                 "\nx: planned cuts; arrows: expected pedicels; cyan rings: cuts after laser verification", fontsize=10)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
