#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Circle fits against the KCR lower bound (docs/hydrus_fitting.md).

Reads the CSV of `hydrus_eval kcr` and writes docs/img/hydrus_kcr.png: the
robust RMS error (1.4826 x median |error|) of centre x, centre y and radius
over the bound's standard deviation, against the arc covered, one line per
method, for every noise level. Prints the Markdown table of the document.

    build/hydrus_fitting/hydrus_eval kcr --out /tmp/kcr.csv
    .venv/bin/python scripts/plots/hydrus_kcr.py /tmp/kcr.csv docs/img/hydrus_kcr.png
"""
import csv
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

METHODS = ["kasa", "hyper", "geometric", "geometric_unbiased", "geometric_second_order", "robust", "known_radius"]
COLOURS = {"kasa": "tab:red", "hyper": "tab:orange", "geometric": "tab:blue",
           "geometric_unbiased": "tab:green", "geometric_second_order": "black", "robust": "tab:purple",
           "known_radius": "tab:grey"}


def main(argv):
    if len(argv) != 3:
        print(__doc__)
        return 2
    rows = list(csv.DictReader(open(argv[1])))
    if not rows:
        print(f"{argv[1]}: no rows")
        return 1
    sigmas = sorted({float(r["sigma_m"]) for r in rows})
    data = defaultdict(list)  # (method, sigma) -> rows sorted by arc
    for r in rows:
        data[(r["method"], float(r["sigma_m"]))].append(r)
    for v in data.values():
        v.sort(key=lambda r: float(r["arc_deg"]))

    fig, axes = plt.subplots(len(sigmas), 3, figsize=(13, 3.0 * len(sigmas)), sharex=True, squeeze=False)
    for i, s in enumerate(sigmas):
        for j, (key, label) in enumerate([("cx", "centre x"), ("cy", "centre y"), ("r", "radius")]):
            ax = axes[i][j]
            for m in METHODS:
                rs = data.get((m, s))
                if not rs:
                    continue
                arcs = [float(r["arc_deg"]) for r in rs]
                ratio = [float(r[f"ratio_{key}"]) for r in rs]
                pts = [(a, q) for a, q in zip(arcs, ratio) if q > 0]
                if pts:
                    ax.plot(*zip(*pts), "o-", ms=3, color=COLOURS[m], label=m)
            ax.axhline(1.0, color="k", lw=0.8)
            ax.axhline(1.1, color="k", lw=0.8, ls="--")
            ax.axvspan(90, 360, color="0.93", zorder=0)
            ax.set_yscale("log")
            ax.set_ylim(0.5, 20)
            ax.set_title(f"{label}, sigma {s * 1000:.1f} mm", fontsize=9)
            if j == 0:
                ax.set_ylabel("robust RMS / KCR SD")
            if i == len(sigmas) - 1:
                ax.set_xlabel("arc [deg]")
    axes[0][0].legend(fontsize=7, loc="upper right")
    fig.suptitle("Circle fits vs the KCR bound (100 points, r = 15 cm; shaded: arcs > 90 deg, dashed: +10 %)")
    fig.tight_layout()
    fig.savefig(argv[2], dpi=110)
    print(f"wrote {argv[2]}")

    # The table: worst ratio over (cx, cy, r) and noise levels, per method and arc.
    arcs = sorted({float(r["arc_deg"]) for r in rows})
    print("\n| method | " + " | ".join(f"{a:g} deg" for a in arcs) + " |")
    print("|---|" + "---|" * len(arcs))
    for m in METHODS:
        cells = []
        for a in arcs:
            worst = None
            for s in sigmas:
                for r in data.get((m, s), []):
                    if float(r["arc_deg"]) != a:
                        continue
                    keys = ["cx", "cy"] if m == "known_radius" else ["cx", "cy", "r"]
                    q = max(float(r[f"ratio_{k}"]) for k in keys)
                    worst = q if worst is None else max(worst, q)
            cells.append("-" if worst is None else f"{worst:.2f}")
        if any(c != "-" for c in cells):
            print(f"| {m} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
