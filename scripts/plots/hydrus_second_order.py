#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Markdown tables of the second-order analysis in docs/hydrus_fitting.md
(why the fits exceed the KCR bound at 19.6 mm noise), from the CSV of
`hydrus_eval second_order`.

    build/hydrus_fitting/hydrus_eval second_order --trials 20000 --out /tmp/second_order.csv
    .venv/bin/python scripts/plots/hydrus_second_order.py /tmp/second_order.csv [SIGMA_MM]
"""
import csv
import sys


def main(argv):
    if len(argv) not in (2, 3):
        print(__doc__)
        return 2
    rows = list(csv.DictReader(open(argv[1])))
    if not rows:
        print(f"{argv[1]}: no rows")
        return 1
    want = float(argv[2]) if len(argv) == 3 else 19.6
    rows = [r for r in rows if abs(float(r["sigma_m"]) * 1000 - want) < 0.05]
    if not rows:
        print(f"{argv[1]}: no rows at sigma {want} mm")
        return 1
    by = {(r["arc_deg"], r["method"]): r for r in rows}
    arcs = sorted({r["arc_deg"] for r in rows}, key=float)
    comps = [("cy", "centre y"), ("r", "radius")]

    def f(r, key, c):
        return float(r[f"{key}_{c}"])

    print(f"Geometric fit, sigma {want} mm, {rows[0]['draws']} draws:\n")
    print("| arc | | metric (Monte-Carlo) | its Taylor series to a3 | RMS: Monte-Carlo | RMS: 2nd-order prediction "
          "| sigma^4 E[a2^2] | normal x tangential | normal x normal | tangential x tangential | (mean a2)^2 |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for a in arcs:
        r = by.get((a, "geometric"))
        if not r:
            continue
        for c, name in comps:
            print(f"| {a} deg | {name} | {f(r, 'mc_robust', c):.3f} | {f(r, 'series3_robust', c):.3f} "
                  f"| {f(r, 'mc_rms', c):.3f} | {f(r, 'second_order', c):.3f} | {f(r, 'mse_a2sq', c):.3f} "
                  f"| {f(r, 'a2sq_cross', c):.3f} | {f(r, 'a2sq_normal', c):.3f} | {f(r, 'a2sq_tangential', c):.3f} "
                  f"| {f(r, 'mse_bias2', c):.3f} |")
    print(f"\nEstimators, sigma {want} mm: metric / best constant shift:\n")
    print("| arc | | geometric | Hyper | end-weighted | first order + the shared cross term | second-order correction |")
    print("|---|---|---|---|---|---|---|")
    for a in arcs:
        for c, name in comps:
            cells = []
            for m in ("geometric", "hyper", "end_weighted"):
                r = by.get((a, m))
                cells.append(f"{f(r, 'mc_robust', c):.3f} / {f(r, 'mc_shorth', c):.3f}" if r else "-")
            g = by.get((a, "geometric"))
            cells.append(f"{f(g, 'forced_robust', c):.3f} / {f(g, 'forced_shorth', c):.3f}" if g else "-")
            r = by.get((a, "geometric_second_order"))
            cells.append(f"{f(r, 'mc_robust', c):.3f} / {f(r, 'mc_shorth', c):.3f}" if r else "-")
            print(f"| {a} deg | {name} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
