#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Plots of a `tinyline calib fit|diagnose --report DIR` report.

Reads DIR/summary.json, DIR/residuals.csv (held-out read-outs with every
candidate covariate and the residual before/after the accepted terms) and
DIR/curve.csv (data points and the fitted polynomial), and writes into DIR:

  curve.png               distance against the charge ratio X with the fitted curve
  error_by_distance.png   held-out bias and SD per target distance, before and after
  residual_<name>.png     held-out residual against each covariate, before and after
  residual_material.png   per material (when the data names materials)

A `tinyline calib measured --report DIR` report instead holds
DIR/measured_materials.csv and DIR/measured_curves.csv; then it writes

  measured_materials.png  Table 3.2: bias against reflectance, and what the best effect leaves
  measured_curves.png     the real sensors' curves: residual of the declared model and of the best

Run with the test virtual env: .venv/bin/python scripts/plots/calib_report.py DIR
"""
import csv
import json
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

NON_COVARIATES = {"line", "distance_m", "target_group", "material", "residual_before_m", "residual_after_m"}


def read_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def column(rows, name):
    out = np.empty(len(rows))
    for i, r in enumerate(rows):
        v = r.get(name, "")
        out[i] = float(v) if v not in ("", None, "null") else math.nan
    return out


def binned(x, y, max_bins=24):
    """Per bin of x: centre, mean and SD of y. Few distinct values: one bin each."""
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size == 0:
        return np.array([]), np.array([]), np.array([])
    values = np.unique(x)
    if values.size <= max_bins or (values.size <= 300 and np.all(values == np.round(values))):
        centres, means, sds = [], [], []
        for v in values:
            sel = y[x == v]
            centres.append(v)
            means.append(sel.mean())
            sds.append(sel.std())
        return np.array(centres), np.array(means), np.array(sds)
    edges = np.unique(np.quantile(x, np.linspace(0, 1, max_bins + 1)))
    idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)
    centres, means, sds = [], [], []
    for b in range(edges.size - 1):
        sel = idx == b
        if sel.sum() < 3:
            continue
        centres.append(np.median(x[sel]))
        means.append(y[sel].mean())
        sds.append(y[sel].std())
    return np.array(centres), np.array(means), np.array(sds)


def residual_plot(rows, name, out_path, title_suffix):
    x = column(rows, name)
    before = column(rows, "residual_before_m") * 100.0
    after = column(rows, "residual_after_m") * 100.0
    if np.isfinite(x).sum() < 10 or np.unique(x[np.isfinite(x)]).size < 2:
        return False
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8), sharey=True)
    rng = np.random.default_rng(0)
    pick = np.arange(len(rows))
    if pick.size > 4000:
        pick = rng.choice(pick, 4000, replace=False)
    for ax, y, label, colour in ((axes[0], before, "before", "tab:red"), (axes[1], after, "after", "tab:blue")):
        ax.scatter(x[pick], y[pick], s=3, alpha=0.25, color=colour, linewidths=0)
        c, m, s = binned(x, y)
        if c.size:
            ax.plot(c, m, color="black", lw=1.5, label="binned mean")
            ax.fill_between(c, m - s, m + s, color="grey", alpha=0.25, label="mean ± SD")
        ax.axhline(0.0, color="black", lw=0.6)
        ok = np.isfinite(y)
        rmse = math.sqrt(np.mean(y[ok] ** 2)) if ok.any() else math.nan
        ax.set_title(f"{label}: RMSE {rmse:.2f} cm")
        ax.set_xlabel(name)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("residual (model - truth) [cm]")
    lim = np.nanpercentile(np.abs(np.concatenate([before, after])), 99.5)
    if np.isfinite(lim) and lim > 0:
        axes[0].set_ylim(-1.2 * lim, 1.2 * lim)
    axes[1].legend(loc="upper right", fontsize=8)
    fig.suptitle(f"Held-out residual against {name}{title_suffix}")
    fig.tight_layout()
    fig.savefig(out_path, dpi=110)
    plt.close(fig)
    return True


def error_by_distance(rows, out_path):
    groups = column(rows, "target_group")
    dist = column(rows, "distance_m")
    fig, ax = plt.subplots(figsize=(8, 4))
    for key, label, colour in (("residual_before_m", "before", "tab:red"), ("residual_after_m", "after", "tab:blue")):
        y = column(rows, key) * 100.0
        xs, bias, sd = [], [], []
        for g in np.unique(groups[np.isfinite(groups)]):
            sel = (groups == g) & np.isfinite(y)
            if sel.sum() < 3:
                continue
            xs.append(np.median(dist[sel]))
            bias.append(y[sel].mean())
            sd.append(y[sel].std())
        if xs:
            order = np.argsort(xs)
            xs, bias, sd = np.array(xs)[order], np.array(bias)[order], np.array(sd)[order]
            ax.errorbar(xs, bias, yerr=sd, fmt="o-", ms=3, capsize=2, color=colour, label=f"{label}: bias ± SD")
    ax.axhline(0.0, color="black", lw=0.6)
    ax.set_xlabel("target distance [m]")
    ax.set_ylabel("error [cm]")
    ax.set_title("Held-out error by target distance")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_path, dpi=110)
    plt.close(fig)


def curve_plot(path, out_path):
    rows = read_rows(path)
    data = [(float(r["ratio"]), float(r["distance_m"])) for r in rows if r["kind"] == "data"]
    model = [(float(r["ratio"]), float(r["distance_m"])) for r in rows if r["kind"] == "model"]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    if data:
        d = np.array(data)
        ax.scatter(d[:, 0], d[:, 1], s=3, alpha=0.3, color="tab:grey", linewidths=0, label="read-outs (truth)")
    if model:
        m = np.array(model)
        ax.plot(m[:, 0], m[:, 1], color="tab:red", lw=1.8, label="fitted polynomial (Eq. 3.18) at T_ref")
    ax.set_xlabel("charge ratio X (Eq. 3.16)")
    ax.set_ylabel("distance [m]")
    ax.set_title("Fitted curve")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_path, dpi=110)
    plt.close(fig)


def material_plot(rows, out_path):
    names = sorted({r["material"] for r in rows if r.get("material")})
    if len(names) < 2:
        return False
    fig, ax = plt.subplots(figsize=(9, 4))
    width = 0.38
    for k, (key, label, colour) in enumerate(
        (("residual_before_m", "before", "tab:red"), ("residual_after_m", "after", "tab:blue"))
    ):
        y = column(rows, key) * 100.0
        means, sds = [], []
        for n in names:
            sel = np.array([r["material"] == n for r in rows]) & np.isfinite(y)
            means.append(y[sel].mean() if sel.any() else math.nan)
            sds.append(y[sel].std() if sel.any() else math.nan)
        ax.bar(np.arange(len(names)) + (k - 0.5) * width, means, width, yerr=sds, capsize=2, color=colour, label=label)
    ax.axhline(0.0, color="black", lw=0.6)
    ax.set_xticks(np.arange(len(names)))
    ax.set_xticklabels(names, rotation=30, ha="right")
    ax.set_ylabel("held-out bias ± SD [cm]")
    ax.set_title("Held-out error by material (the driver does not know the material; the term uses a covariate)")
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_path, dpi=110)
    plt.close(fig)
    return True


def measured_plots(d):
    mats = read_rows(os.path.join(d, "measured_materials.csv"))
    q = column(mats, "reflectance")
    bias = column(mats, "bias_cm")
    sd = column(mats, "sd_cm")
    left = column(mats, "loo_residual_cm")
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    ax[0].errorbar(q, bias, yerr=sd, fmt="o", color="C0", label="measured bias (SD)")
    for r, x, y in zip(mats, q, bias):
        ax[0].annotate(r["material"], (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
    ax[0].set_xscale("log")
    ax[0].set_xlabel("reflectance the sensor reports [mV/pulse]")
    ax[0].set_ylabel("bias at 30 cm [cm]")
    ax[0].set_title("Table 3.2, calibrated on white paper")
    ax[0].axhline(0.0, color="0.6", lw=0.8)
    ax[1].bar([r["material"] for r in mats], np.nan_to_num(left), color="C1")
    ax[1].set_ylabel("left over, leave-one-material-out [cm]")
    ax[1].set_title("what the best effect leaves")
    ax[1].tick_params(axis="x", rotation=60, labelsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(d, "measured_materials.png"), dpi=110)
    plt.close(fig)
    curves = read_rows(os.path.join(d, "measured_curves.csv"))
    sensors = sorted({r["sensor"] for r in curves})
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    for i, s in enumerate(sensors):
        rows = [r for r in curves if r["sensor"] == s]
        l = column(rows, "l_cm")
        ax[0].plot(l, column(rows, "declared_heldout_residual_cm"), color=f"C{i}", label=s)
        ax[1].plot(l, column(rows, "best_heldout_residual_cm"), color=f"C{i}", label=s)
    ax[0].set_title("declared (Eq. 3.16, Rsen = 1), held out by blocks of distance")
    ax[1].set_title("the chosen model, held out by blocks of distance")
    for a in ax:
        a.set_xlabel("distance the factory curve reads [cm]")
        a.set_ylabel("curve - model, held out [cm]")
        a.axhline(0.0, color="0.6", lw=0.8)
        a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(d, "measured_curves.png"), dpi=110)
    plt.close(fig)


def main(argv):
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    d = argv[1]
    if os.path.exists(os.path.join(d, "measured_materials.csv")):
        measured_plots(d)
        return 0
    with open(os.path.join(d, "summary.json")) as f:
        summary = json.load(f)
    rows = read_rows(os.path.join(d, "residuals.csv"))
    written = []
    curve_plot(os.path.join(d, "curve.csv"), os.path.join(d, "curve.png"))
    written.append("curve.png")
    if rows:
        error_by_distance(rows, os.path.join(d, "error_by_distance.png"))
        written.append("error_by_distance.png")
        effects = {e["covariate"] for e in summary.get("effects", [])}
        for name in rows[0].keys():
            if name in NON_COVARIATES:
                continue
            suffix = " (term added)" if name in effects else ""
            if residual_plot(rows, name, os.path.join(d, f"residual_{name}.png"), suffix):
                written.append(f"residual_{name}.png")
        if material_plot(rows, os.path.join(d, "residual_material.png")):
            written.append("residual_material.png")
    del written  # the tool lists the figures in report.md
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
