#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Markdown tables of docs/hydrus_fitting.md from the CSVs of `hydrus_eval`.

    build/hydrus_fitting/hydrus_eval robustness --out /tmp/robustness.csv
    build/hydrus_fitting/hydrus_eval ray_noise --out /tmp/ray_noise.csv
    .venv/bin/python scripts/plots/hydrus_tables.py /tmp/robustness.csv /tmp/ray_noise.csv
"""
import csv
import sys
from collections import defaultdict

ROBUST = ["plain", "msac", "msac_views", "msac_views_selffilter", "msac_views_radius_prior", "msac_views_known_radius"]
RAY = ["kasa", "msac", "msac_incidence", "estimator_plain_refit", "estimator"]


def robustness(path):
    rows = list(csv.DictReader(open(path)))
    by = defaultdict(dict)
    for r in rows:
        by[int(r["clutter_objects"])][r["method"]] = r
    print("| clutter | outliers offered | " + " | ".join(ROBUST) + " |")
    print("|---|---|" + "---|" * len(ROBUST))
    for c in sorted(by):
        m = by[c]
        frac = float(m["msac"]["median_outlier_fraction"]) if "msac" in m else float("nan")
        cells = [f"{100.0 * int(m[k]['correct']) / int(m[k]['trials']):.1f} %" if k in m else "-" for k in ROBUST]
        print(f"| {c} | {100 * frac:.0f} % | " + " | ".join(cells) + " |")
    views = [r for r in rows if r["method"] == "msac_views" and int(r["correct"]) > 0]
    if views:
        e = [float(r["median_centre_error_m"]) * 1000 for r in views]
        print(f"\nmsac_views median centre error of the trials: {min(e):.2f}-{max(e):.2f} mm")


def ray_noise(path):
    rows = list(csv.DictReader(open(path)))
    for scale in sorted({r["noise_scale"] for r in rows}, key=float):
        print(f"\nnoise x {scale}: ratio to the KCR SD (centre x / centre y / radius)")
        print("| joints | arc | " + " | ".join(RAY) + " |")
        print("|---|---|" + "---|" * len(RAY))
        for j in sorted({r["joint_deg"] for r in rows}, key=float):
            sel = {r["variant"]: r for r in rows if r["joint_deg"] == j and r["noise_scale"] == scale}
            if not sel:
                continue
            arc = float(next(iter(sel.values()))["arc_deg"])
            cells = []
            for v in RAY:
                r = sel.get(v)
                cells.append("-" if r is None else "/".join(f"{float(r[k]):.2f}" for k in ("ratio_cx", "ratio_cy", "ratio_r")))
            print(f"| {float(j):g} deg | {arc:.0f} deg | " + " | ".join(cells) + " |")


def main(argv):
    if len(argv) != 3:
        print(__doc__)
        return 2
    robustness(argv[1])
    ray_noise(argv[2])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
