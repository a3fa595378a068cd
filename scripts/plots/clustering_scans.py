#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Pictures of simulated scans with their clusters (docs/laser_clustering.md).

Reads the scans the evaluation wrote (laser_clustering_eval --out DIR:
DIR/scans/*.csv, DIR/wrench_sweeps.csv) and draws, per scan, the thesis's
Figure 4.6 view (range per pixel: raw, filtered, each cluster a "ladder"
step) above a plan view of the points coloured by what the simulator says
they hit; per tomato look (scans/look_*.csv) the plan view with the vision's
tomatoes before and after the registration; plus the wrench pitch sweeps.

usage: .venv/bin/python scripts/plots/clustering_scans.py DIR [--out docs/img] [--only NAME ...]
"""
import argparse
import csv
import glob
import math
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

TRUTH_COLOURS = {
    "target": "#d62728", "pedicel": "#ff7f0e", "tomato": "#8c564b", "stem": "#2ca02c", "leaf": "#17becf",
    "stick": "#d62728", "stick_mixed": "#ff9896", "panel": "#7f7f7f", "panel_mixed": "#c7c7c7", "none": "#bbbbbb",
}


def read(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    def num(r, k):
        v = r[k]
        return float(v) if v not in ("", "nan", "-nan") else math.nan
    return [{"pixel": int(r["pixel"]), "angle": num(r, "angle_rad"), "range": num(r, "range_m"),
             "filtered": num(r, "filtered_m"), "refl": num(r, "reflectance"), "label": int(r["label"]),
             "chosen": r["chosen"] == "1", "truth": r["truth"]} for r in rows]


def plan_points(ax, rows):
    """The scan's points in the laser plane [cm], coloured by what each ray hits."""
    for kind in sorted({r["truth"] for r in rows}):
        pts = [r for r in rows if r["truth"] == kind and not math.isnan(r["range"])]
        ax.plot([r["range"] * math.sin(r["angle"]) * 100 for r in pts], [r["range"] * math.cos(r["angle"]) * 100 for r in pts],
                ".", ms=4, color=TRUTH_COLOURS.get(kind, "#bbbbbb"), label=f"hits {kind}")


def finish_plan(fig, ax, out):
    """Labels a plan view in the laser plane and writes the figure."""
    ax.set_xlabel("x along the line [cm]")
    ax.set_ylabel("z forward [cm]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=7, loc="upper right", ncol=2)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def scan_figure(rows, title, out, show_reflectance=False):
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(8, 7.5), gridspec_kw={"height_ratios": [1, 1.3]})
    px = [r["pixel"] for r in rows]
    ax.plot(px, [r["range"] for r in rows], color="#1f77b4", lw=0.8, label="raw range")
    if any(not math.isnan(r["filtered"]) for r in rows):
        ax.plot(px, [r["filtered"] for r in rows], ".", color="#555555", ms=2.5, label="filtered (kept)")
    labels = sorted({r["label"] for r in rows if r["label"] >= 0})
    cmap = plt.get_cmap("tab20")
    for k, lab in enumerate(labels):
        pts = [r for r in rows if r["label"] == lab]
        ranges = [r["filtered"] if not math.isnan(r["filtered"]) else r["range"] for r in pts]
        m = sum(ranges) / len(ranges)
        chosen = any(r["chosen"] for r in pts)
        ax.hlines(m, pts[0]["pixel"] - 0.5, pts[-1]["pixel"] + 0.5, colors="black" if chosen else cmap(k % 20),
                  lw=3.5 if chosen else 2.0, label="chosen" if chosen else None)
    # What each pixel's central ray hits, as ticks along the bottom.
    ax.scatter(px, [0.0] * len(px), marker="|", s=30, c=[TRUTH_COLOURS.get(r["truth"], "#bbbbbb") for r in rows])
    ax.set_ylim(bottom=0.0)
    if show_reflectance:
        rx = ax.twinx()
        rx.plot(px, [r["refl"] for r in rows], color="#9467bd", lw=0.8, alpha=0.8)
        rx.set_ylabel("reflectance (driver's figure)", color="#9467bd")
        rx.set_ylim(bottom=0.0)
    ax.set_xlabel("pixel")
    ax.set_ylabel("range [m]")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    plan_points(bx, rows)
    ch = [r for r in rows if r["chosen"] and not math.isnan(r["range"])]
    if ch:
        bx.plot([r["range"] * math.sin(r["angle"]) * 100 for r in ch], [r["range"] * math.cos(r["angle"]) * 100 for r in ch],
                "o", mfc="none", mec="black", ms=7, label="chosen cluster")
    finish_plan(fig, bx, out)


def look_figure(rows, tomatoes_path, title, out):
    """A tomato look: the scan through the tomatoes in plan view, the vision's
    tomato cross-sections where it expected them (dashed) and where the
    registration moved them (solid)."""
    with open(tomatoes_path) as f:
        tomatoes = list(csv.DictReader(f))
    fig, ax = plt.subplots(figsize=(8, 5.5))
    plan_points(ax, rows)
    for k, t in enumerate(tomatoes):
        h, radius = float(t["height_m"]), float(t["radius_m"])
        if abs(h) >= radius:
            continue
        r = math.sqrt(radius * radius - h * h) * 100
        x, z = float(t["expected_x_m"]) * 100, float(t["expected_z_m"]) * 100
        ax.add_patch(plt.Circle((x, z), r, fill=False, ls="--", color="#7f7f7f", label="vision's tomatoes" if k == 0 else None))
        if t["registered"] == "1":
            dx, dz = float(t["shift_x_m"]) * 100, float(t["shift_z_m"]) * 100
            ax.add_patch(plt.Circle((x + dx, z + dz), r, fill=False, color="#d62728", lw=1.5,
                                    label="registered" if k == 0 else None))
    ax.plot([0], [0], "k^", ms=8, label="laser")
    ax.set_title(title, fontsize=9)
    finish_plan(fig, ax, out)


def sweep_figure(path, out):
    sweeps = {}
    with open(path) as f:
        for r in csv.DictReader(f):
            sweeps.setdefault(r["seed"], []).append(r)
    fig, ax = plt.subplots(figsize=(7, 4))
    cmap = plt.get_cmap("tab10")
    for k, (seed, rows) in enumerate(sorted(sweeps.items(), key=lambda kv: int(kv[0]))):
        p = [float(r["pitch_deg"]) for r in rows]
        v = [float(r["reflectance"]) for r in rows]
        ax.plot(p, v, "o-", color=cmap(k), ms=3, label=f"trial {seed}")
        ax.axvline(float(rows[0]["true_pitch_deg"]), color=cmap(k), ls="--", lw=0.8)
        ax.axvline(float(rows[0]["best_pitch_deg"]), color=cmap(k), ls=":", lw=1.2)
    ax.set_xlabel("gripper pitch [deg]")
    ax.set_ylabel("surface reflectance (driver's figure)")
    ax.set_title("wrench pitch sweeps: dashed = true square pitch, dotted = found", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--out", default="docs/img")
    ap.add_argument("--only", nargs="*", help="scan file stems to draw (default: all)")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    for path in sorted(glob.glob(os.path.join(args.dir, "scans", "*.csv"))):
        stem = os.path.splitext(os.path.basename(path))[0]
        if args.only and stem not in args.only or stem.endswith("_tomatoes"):
            continue
        if stem.startswith("look_"):
            look_figure(read(path), path.replace(".csv", "_tomatoes.csv"), stem.replace("_", " ") + ": the tomato look",
                        os.path.join(args.out, f"clustering_{stem}.png"))
            continue
        scan_figure(read(path), stem.replace("_", " "), os.path.join(args.out, f"clustering_{stem}.png"),
                    show_reflectance=stem.startswith("stick"))
    sweeps = os.path.join(args.dir, "wrench_sweeps.csv")
    if os.path.exists(sweeps) and (not args.only or "wrench_sweeps" in args.only):
        sweep_figure(sweeps, os.path.join(args.out, "clustering_wrench_sweeps.png"))


if __name__ == "__main__":
    main()
