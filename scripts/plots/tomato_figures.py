#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Pictures of docs/tomato_reasoning.md from tomato_dump's CSV files:
a cloud with the fitted spheres, the force graph with the pedicel
expectations, and the pedicel distribution on the sphere (thesis Figure 4.5).

  build/tomato_reasoning/tomato_dump B 4 /tmp/dump_B_4
  build/tomato_reasoning/tomato_dump C 7 /tmp/dump_C_7
  .venv/bin/python scripts/plots/tomato_figures.py /tmp/dump_B_4 /tmp/dump_C_7 --out docs/img
"""
import argparse
import csv
import math
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def rows(path):
    with open(path) as f:
        return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]


def load(d):
    pts = np.loadtxt(os.path.join(d, "points.csv"), delimiter=",", skiprows=1, ndmin=2)
    return pts, rows(os.path.join(d, "spheres.csv")), rows(os.path.join(d, "edges.csv")), os.path.basename(d.rstrip("/"))


def image_plane(ax, pts, spheres, title, red_only=False):
    """Orthographic view along the camera axis (x right, y down)."""
    sel = pts[:, 6] > 0 if red_only else np.ones(len(pts), bool)
    ax.scatter(pts[sel, 0], pts[sel, 1], c=pts[sel, 3:6] / 255.0, s=0.3, linewidths=0)
    for s in spheres:
        ax.add_patch(plt.Circle((s["cx"], s["cy"]), s["radius"], fill=False, ec="yellow", lw=1.5))
        if not math.isnan(s["tcx"]):
            ax.plot(s["tcx"], s["tcy"], "+", color="cyan", ms=8)
    ax.set_aspect("equal")
    ax.invert_yaxis()
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m] (down)")
    ax.set_title(title, fontsize=9)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--out", default="docs/img")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    data = [load(d) for d in args.dirs]

    # 1. cloud with fitted spheres
    fig, axes = plt.subplots(1, len(data), figsize=(6 * len(data), 5.5))
    for ax, (pts, spheres, _edges, name) in zip(np.atleast_1d(axes), data):
        cx = np.mean([s["cx"] for s in spheres]) if spheres else 0
        cy = np.mean([s["cy"] for s in spheres]) if spheres else 0
        image_plane(ax, pts, spheres, f"{name}: {len(spheres)} spheres (yellow), true centres (cyan +)")
        ax.set_xlim(cx - 0.2, cx + 0.2)
        ax.set_ylim(cy + 0.2, cy - 0.2)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "tomato_cloud_spheres.png"), dpi=110)
    plt.close(fig)

    # 2. force graph: contact edges, expected and true pedicel directions, pick ranks
    pts, spheres, edges, name = data[-1]
    fig, ax = plt.subplots(figsize=(7, 6.5))
    image_plane(ax, pts, spheres, "", red_only=True)
    for e in edges:
        a, b = spheres[int(e["i"])], spheres[int(e["j"])]
        ax.plot([a["cx"], b["cx"]], [a["cy"], b["cy"]], "-", color="royalblue", lw=2.5)
    for s in spheres:
        L = 0.05
        ax.annotate("", xy=(s["cx"] + L * s["ex"], s["cy"] + L * s["ey"]), xytext=(s["cx"], s["cy"]),
                    arrowprops=dict(arrowstyle="->", color="green", lw=2))
        if not math.isnan(s["tpx"]):
            ax.annotate("", xy=(s["cx"] + L * s["tpx"], s["cy"] + L * s["tpy"]), xytext=(s["cx"], s["cy"]),
                        arrowprops=dict(arrowstyle="->", color="black", lw=1.2, ls="--"))
        ax.text(s["cx"], s["cy"] + 0.012, f"#{int(s['pick_rank']) + 1}", ha="center", fontsize=10, weight="bold")
    ax.set_title(f"{name}: contact graph (blue, Eq. 4.17), expected pedicel force direction (green, Eq. 4.22),\n"
                 "true pedicel (black dashed), pick order (#, Eq. 4.23)", fontsize=9)
    cx = np.mean([s["cx"] for s in spheres])
    cy = np.mean([s["cy"] for s in spheres])
    ax.set_xlim(cx - 0.15, cx + 0.15)
    ax.set_ylim(cy + 0.13, cy - 0.17)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "tomato_force_graph.png"), dpi=110)
    plt.close(fig)

    # 3. pedicel distribution on the sphere (Figure 4.5): the first sphere with two or more edges
    d = args.dirs[-1]
    pick = next((s for s in spheres if s["edges"] >= 2), spheres[0])
    k = int(pick["k"])
    grid = np.loadtxt(os.path.join(d, f"grid_{k}.csv"), delimiter=",")
    fig, ax = plt.subplots(figsize=(8, 4.2))
    im = ax.imshow(grid, extent=[-180, 180, 180, 0], aspect="auto", cmap="jet")
    fig.colorbar(im, ax=ax, label="density [1/sr]")

    def angles(x, y, z):
        return math.degrees(math.atan2(y, x)), math.degrees(math.acos(max(-1, min(1, z))))

    ax.plot(*angles(pick["gux"], pick["guy"], pick["guz"]), "wo", mfc="none", ms=12, mew=2, label="expectation")
    if not math.isnan(pick["gtx"]):
        ax.plot(*angles(pick["gtx"], pick["gty"], pick["gtz"]), "wx", ms=12, mew=2, label="truth")
    ax.set_xlabel("phi [deg]")
    ax.set_ylabel("theta from straight up [deg]")
    ax.set_title(f"{name}, tomato {k} ({int(pick['edges'])} contacts): pedicel direction distribution "
                 f"(Eq. 4.18-4.22), median spread {pick['spread50_deg']:.0f} deg", fontsize=9)
    ax.legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "tomato_pedicel_distribution.png"), dpi=110)
    plt.close(fig)
    print("wrote", ", ".join(os.path.join(args.out, f) for f in
                             ["tomato_cloud_spheres.png", "tomato_force_graph.png", "tomato_pedicel_distribution.png"]))


if __name__ == "__main__":
    main()
