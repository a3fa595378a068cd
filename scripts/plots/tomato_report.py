#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Tables of docs/tomato_reasoning.md from tomato_eval's output, with 95 %
intervals: Wilson score intervals for rates, and for medians and 95th
percentiles a bootstrap over trusses (tomatoes of one truss are not
independent, so whole trusses are resampled).

usage: .venv/bin/python scripts/plots/tomato_report.py DIR [--variant default] [--boot 1000]
"""
import argparse
import csv
import math
import os
from collections import defaultdict

import numpy as np

THESIS = {"A": (36, 36), "B": (49, 57), "C": (33, 43)}
TABLE_43 = {"random_offset": ("random offset < 5 cm", 56, 2, 3, 61), "as_recognised": ("recognition error", 26, 11, 2, 39)}


def wilson(k, n, z=1.96):
    if n == 0:
        return float("nan"), float("nan"), float("nan")
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return p, max(0.0, c - h), min(1.0, c + h)


def rate(k, n):
    p, lo, hi = wilson(k, n)
    return f"{k}/{n} = {100 * p:.1f}% [{100 * lo:.1f}, {100 * hi:.1f}]"


def boot(groups, stat, n_boot, rng):
    """stat over the pooled values, and its 95 % interval resampling the groups (trusses)."""
    keys = list(groups)
    pooled = np.concatenate([groups[k] for k in keys]) if keys else np.array([])
    pooled = pooled[np.isfinite(pooled)]
    if len(pooled) == 0:
        return "n/a"
    est = stat(pooled)
    reps = []
    for _ in range(n_boot):
        pick = rng.integers(0, len(keys), len(keys))
        v = np.concatenate([groups[keys[i]] for i in pick])
        v = v[np.isfinite(v)]
        if len(v):
            reps.append(stat(v))
    lo, hi = np.percentile(reps, [2.5, 97.5])
    return f"{est:.2f} [{lo:.2f}, {hi:.2f}]"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--variant", default="default")
    ap.add_argument("--boot", type=int, default=1000)
    args = ap.parse_args()
    rng = np.random.default_rng(1)
    with open(os.path.join(args.dir, f"{args.variant}_tomatoes.csv")) as f:
        rows = list(csv.DictReader(f))
    by_class = defaultdict(list)
    for r in rows:
        by_class[r["class"]].append(r)
    med = lambda v: float(np.median(v))  # noqa: E731
    p95 = lambda v: float(np.percentile(v, 95))  # noqa: E731

    print("| class | trusses | detected, all fruit | detected, fruit >= 25 % visible | thesis (SD/trials) |")
    print("|---|---|---|---|---|")
    for c in sorted(by_class):
        rs = by_class[c]
        det = [int(r["detection"]) >= 0 for r in rs]
        vis = [float(r["visible_share"]) >= 0.25 for r in rs]
        seeds = len({r["seed"] for r in rs})
        print(f"| {c} | {seeds} | {rate(sum(det), len(rs))} | {rate(sum(d and v for d, v in zip(det, vis)), sum(vis))} | "
              f"{rate(*THESIS[c])} |")
    print()
    print("Errors of the detected tomatoes (median and 95th percentile, 95 % bootstrap interval over trusses):")
    print()
    print("| class | centre median [mm] | centre p95 [mm] | |radius| median [mm] | |radius| p95 [mm] |")
    print("|---|---|---|---|---|")
    for c in sorted(by_class):
        g_c, g_r = defaultdict(list), defaultdict(list)
        for r in by_class[c]:
            if int(r["detection"]) >= 0:
                g_c[r["seed"]].append(float(r["centre_error_mm"]))
                g_r[r["seed"]].append(abs(float(r["radius_error_mm"])))
        g_c = {k: np.array(v) for k, v in g_c.items()}
        g_r = {k: np.array(v) for k, v in g_r.items()}
        print(f"| {c} | {boot(g_c, med, args.boot, rng)} | {boot(g_c, p95, args.boot, rng)} | "
              f"{boot(g_r, med, args.boot, rng)} | {boot(g_r, p95, args.boot, rng)} |")
    print()
    print("| class | pedicel angle median [deg] | pedicel p95 [deg] | straight up (no reasoning) median [deg] | "
          "truth in HPD50 | planned cut covers the true pedicel |")
    print("|---|---|---|---|---|---|")
    for c in sorted(by_class):
        g_p, g_g = defaultdict(list), defaultdict(list)
        hpd = cover = n = 0
        for r in by_class[c]:
            if int(r["detection"]) >= 0:
                g_p[r["seed"]].append(float(r["pedicel_error_deg"]))
                g_g[r["seed"]].append(float(r["gravity_only_error_deg"]))
                hpd += int(r["truth_in_hpd50"])
                cover += int(r["cut_covers_truth"])
                n += 1
        g_p = {k: np.array(v) for k, v in g_p.items()}
        g_g = {k: np.array(v) for k, v in g_g.items()}
        print(f"| {c} | {boot(g_p, med, args.boot, rng)} | {boot(g_p, p95, args.boot, rng)} | {boot(g_g, med, args.boot, rng)} | "
              f"{rate(hpd, n)} | {rate(cover, n)} |")

    kpath = os.path.join(args.dir, "kappa_sweep.csv")
    if os.path.exists(kpath):
        print()
        print("| kernel kappa | truth in HPD50 (all classes) |")
        print("|---|---|")
        with open(kpath) as f:
            for r in csv.DictReader(f):
                n = int(r["n"])
                print(f"| {float(r['kappa']):g} | {rate(round(float(r['hpd50_hit_rate']) * n), n)} |")

    vpath = os.path.join(args.dir, "verification.csv")
    if os.path.exists(vpath):
        with open(vpath) as f:
            vs = list(csv.DictReader(f))
        print()
        print("| case | class | picks | blades on the pedicel after verification | vision alone | wrong | out of view | nothing found |")
        print("|---|---|---|---|---|---|---|---|")
        for case in ["random_offset", "as_recognised"]:
            for c in sorted({v["class"] for v in vs}) + ["all"]:
                sel = [v for v in vs if v["case"] == case and (c == "all" or v["class"] == c)]
                n = len(sel)
                cnt = lambda verdict: sum(v["verdict"] == verdict for v in sel)  # noqa: E731
                print(f"| {case} | {c} | {n} | {rate(cnt('aligned'), n)} | {rate(sum(int(v['vision_on_pedicel']) for v in sel), n)} | "
                      f"{rate(cnt('wrong'), n)} | {rate(cnt('out_of_view'), n)} | {rate(cnt('nothing_found'), n)} |")
            name, al, wr, ov, n = TABLE_43[case]
            print(f"| thesis Table 4.3: {name} | | {n} | {rate(al, n)} | | {rate(wr, n)} | {rate(ov, n)} | |")


if __name__ == "__main__":
    main()
