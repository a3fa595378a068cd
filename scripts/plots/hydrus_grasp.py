#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The Hydrus grasp in the simulator (docs/hydrus_fitting.md).

Reads the CSVs of `hydrus_sim_eval` and writes

  <prefix>_centre_error.png  centre error over the manoeuvre per schedule,
                             with the share of corrupted cylinder pixels
  <prefix>_circles.png       fitted circles against the truth (robot frame)
                             in the three phases (colouring schedule)
  <prefix>_crosstalk.png     (with --hold FILE) the hold phase started with
                             all pulse trains in phase: all on vs sequenced

and prints the Markdown tables of the document.

    build/hydrus_fitting/hydrus_sim_eval --updates /tmp/u.csv --rates /tmp/r.csv
    build/hydrus_fitting/hydrus_sim_eval --start 10 --end 10.5 --updates /tmp/uh.csv --rates /tmp/rh.csv
    .venv/bin/python scripts/plots/hydrus_grasp.py /tmp/u.csv /tmp/r.csv docs/img/hydrus_grasp --hold /tmp/uh.csv
"""
import csv
import math
import statistics as st
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

SCHEDULES = ["all_on", "time_slicing", "colouring"]
COLOURS = {"all_on": "tab:red", "time_slicing": "tab:blue", "colouring": "tab:green"}
PHASES = [("approach", 0.0, 6.0), ("closing", 6.0, 10.0), ("hold", 10.0, 12.0)]


def load(path):
    rows = list(csv.DictReader(open(path)))
    by = defaultdict(list)
    for r in rows:
        for k, v in list(r.items()):
            if k != "schedule":
                r[k] = float(v)
        by[r["schedule"]].append(r)
    return by


def error_plot(by, out):
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True)
    for s in SCHEDULES:
        rs = by.get(s, [])
        if not rs:
            continue
        t = [r["t_s"] for r in rs]
        e = [r["centre_error_m"] * 100 if r["status"] == 0 else float("nan") for r in rs]
        same = s == "colouring" and [r["centre_error_m"] for r in rs] == [r["centre_error_m"] for r in by.get("time_slicing", [])]
        a1.plot(t, e, ".", ms=3, color=COLOURS[s], label=s + (" (= time_slicing: 4 colours)" if same else ""), alpha=0.7)
        # Pooled over 0.25 s bins: one set per update when sequenced, four when all on.
        bins = defaultdict(lambda: [0.0, 0.0])
        for r in rs:
            b = bins[int(r["t_s"] / 0.25)]
            b[0] += r["corrupted_pixels"]
            b[1] += r["valid_pixels"]
        keys = sorted(bins)
        a2.plot([0.25 * (k + 0.5) for k in keys], [100.0 * bins[k][0] / bins[k][1] if bins[k][1] else float("nan")
                                                   for k in keys], "o-", ms=2, lw=0.9, color=COLOURS[s], label=s)
    for ax in (a1, a2):
        for name, t0, t1 in PHASES:
            ax.axvline(t1, color="0.6", lw=0.6)
    for name, t0, t1 in PHASES:
        a1.text(0.5 * (t0 + t1), 150, name, ha="center", fontsize=8)
    a1.set_yscale("log")
    a1.set_ylim(0.05, 300)
    a1.set_ylabel("centre error [cm]")
    a1.legend(fontsize=8, loc="lower left")
    a2.set_ylabel("cylinder pixels off > 5 cm [%]\n(per 0.25 s)")
    a2.set_xlabel("manoeuvre time [s]")
    fig.suptitle("Hydrus grasp in the simulator: 4 sensors, fly in, close the links, hold")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


def circles_plot(by, out):
    rs = by.get("colouring") or by[next(iter(by))]
    fig, axes = plt.subplots(1, 3, figsize=(12, 4.2))
    for ax, (name, t0, t1) in zip(axes, PHASES):
        sel = [r for r in rs if t0 <= r["t_s"] < t1 and r["status"] == 0]
        # Circles in the robot frame; the truth moves in it while the robot flies.
        step = max(1, len(sel) // 25)
        for r in sel[::step]:
            th = [2 * math.pi * k / 90 for k in range(91)]
            ax.plot([r["centre_x_m"] + r["radius_m"] * math.cos(a) for a in th],
                    [r["centre_y_m"] + r["radius_m"] * math.sin(a) for a in th], color="tab:green", lw=0.6, alpha=0.5)
            ax.plot([r["true_x_m"] + 0.10 * math.cos(a) for a in th],
                    [r["true_y_m"] + 0.10 * math.sin(a) for a in th], color="tab:red", lw=0.6, alpha=0.3)
        ax.plot([0, 0.5], [0, 0], color="tab:blue", lw=3, label="link1 (robot frame)")
        ax.set_aspect("equal")
        ax.set_title(f"{name} ({t0:g}-{t1:g} s): {len(sel)} fits", fontsize=9)
        ax.set_xlabel("x [m]")
        ax.grid(True, lw=0.3)
    axes[0].set_ylabel("y [m]")
    axes[0].plot([], [], color="tab:green", label="fitted")
    axes[0].plot([], [], color="tab:red", label="truth")
    axes[0].legend(fontsize=7, loc="lower right")
    fig.suptitle("Fitted circles (green) and the true cylinder (red), robot frame, colouring schedule")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


def crosstalk_plot(by, out):
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
    for s in SCHEDULES:
        rs = by.get(s, [])
        if not rs:
            continue
        t = [r["t_s"] for r in rs]
        a1.plot(t, [100.0 * r["corrupted_pixels"] / max(1, r["valid_pixels"]) for r in rs], "o-", ms=3,
                color=COLOURS[s], label=s)
        a2.plot(t, [r["centre_error_m"] * 100 if r["status"] == 0 else float("nan") for r in rs], "o-", ms=3,
                color=COLOURS[s], label=s)
    a1.set_ylabel("cylinder pixels off > 5 cm [%]")
    a2.set_ylabel("centre error [cm]")
    a2.set_yscale("log")
    a2.set_xlabel("manoeuvre time [s]")
    a1.legend(fontsize=8)
    fig.suptitle("Hold phase, every pulse train started in phase at 10 s")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


def tables(by, rates_path):
    print("\n| schedule | phase | updates | fits | median centre error [mm] | 95th pct [mm] | updates > 2 cm | median radius error [mm] | pixels off > 5 cm |")
    print("|---|---|---|---|---|---|---|---|---|")
    for s in SCHEDULES:
        for name, t0, t1 in PHASES:
            w = [r for r in by.get(s, []) if t0 <= r["t_s"] < t1]
            ok = [r for r in w if r["status"] == 0]
            if not w:
                continue
            ce = sorted(r["centre_error_m"] * 1000 for r in ok)
            re = [r["radius_error_m"] * 1000 for r in ok]
            p95 = ce[min(len(ce) - 1, int(0.95 * len(ce)))] if ce else float("nan")
            bad = sum(1 for r in w if r["status"] != 0 or r["centre_error_m"] > 0.02)
            v = sum(r["valid_pixels"] for r in w)
            c = sum(r["corrupted_pixels"] for r in w)
            print(f"| {s} | {name} | {len(w)} | {len(ok)} | {st.median(ce):.1f} | {p95:.1f} | {bad} ({100.0 * bad / len(w):.0f} %) | "
                  f"{st.median(re):+.1f} | {100.0 * c / max(1, v):.1f} % |")
    # The approach's fits within 2 cm: their error across (x) and along (y, the
    # direction of flight) the robot frame, where the base's own motion shows.
    print("\n| schedule | approach fits within 2 cm | median centre error [mm] | median x error [mm] | median y error (along the flight) [mm] |")
    print("|---|---|---|---|---|")
    for s in SCHEDULES:
        good = [r for r in by.get(s, []) if r["t_s"] < PHASES[0][2] and r["status"] == 0 and r["centre_error_m"] <= 0.02]
        if not good:
            continue
        print(f"| {s} | {len(good)} | {st.median(r['centre_error_m'] * 1000 for r in good):.1f} | "
              f"{st.median((r['centre_x_m'] - r['true_x_m']) * 1000 for r in good):+.1f} | "
              f"{st.median((r['centre_y_m'] - r['true_y_m']) * 1000 for r in good):+.1f} |")
    rows = list(csv.DictReader(open(rates_path)))
    print("\n| sensor | " + " | ".join(f"{s} [Hz]" for s in SCHEDULES) + " |")
    print("|---|" + "---|" * len(SCHEDULES))
    sensors = sorted({r["sensor"] for r in rows})
    for sen in sensors:
        cells = []
        for s in SCHEDULES:
            r = [x for x in rows if x["schedule"] == s and x["sensor"] == sen]
            cells.append(f"{float(r[0]['rate_hz']):.2f}" if r else "-")
        print(f"| {sen} | " + " | ".join(cells) + " |")


def main(argv):
    args = argv[1:]
    hold = None
    if "--hold" in args:
        i = args.index("--hold")
        hold = args[i + 1]
        del args[i:i + 2]
    if len(args) != 3:
        print(__doc__)
        return 2
    by = load(args[0])
    error_plot(by, args[2] + "_centre_error.png")
    circles_plot(by, args[2] + "_circles.png")
    tables(by, args[1])
    if hold:
        hb = load(hold)
        crosstalk_plot(hb, args[2] + "_crosstalk.png")
        print("\n| schedule | t [s] | sets | crosstalk pulses | pixels off > 5 cm | centre error [mm] |")
        print("|---|---|---|---|---|---|")
        for s in SCHEDULES:
            for r in hb.get(s, [])[:4]:
                e = f"{r['centre_error_m'] * 1000:.1f}" if r["status"] == 0 else "no fit"
                print(f"| {s} | {r['t_s']:.3f} | {int(r['sets'])} | {int(r['crosstalk_pulses'])} | "
                      f"{100.0 * r['corrupted_pixels'] / max(1, r['valid_pixels']):.0f} % | {e} |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
