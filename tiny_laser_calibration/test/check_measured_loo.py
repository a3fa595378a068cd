# SPDX-License-Identifier: Apache-2.0
"""An independent implementation of Table 3.2's leave-one-material-out
(numpy least squares and scikit-learn's LeaveOneOut), held against what
`tinyline calib measured --json` prints.

Usage: check_measured_loo.py MEASURED.yaml REPORT.json
Exit 0 when every form's leave-one-out RMSE, its parameters and the choice
agree; 1 with the differences otherwise.
"""
import json
import math
import sys

import numpy as np
import yaml
from sklearn.linear_model import LinearRegression
from sklearn.model_selection import LeaveOneOut

FORMS = {
    "bias = c (1/q - 1)": [lambda q: 1 / q - 1],
    "bias = c1 (1/q - 1) + c2 (1/q - 1)^2": [lambda q: 1 / q - 1, lambda q: (1 / q - 1) ** 2],
    "bias = c ln q": [np.log],
    "bias = c1 ln q + c2 ln^2 q": [np.log, lambda q: np.log(q) ** 2],
    "bias = c1 ln q + c2 ln^2 q + c3 ln^3 q": [np.log, lambda q: np.log(q) ** 2, lambda q: np.log(q) ** 3],
    "bias = c (q - 1)": [lambda q: q - 1],
    "bias = c1 (q - 1) + c2 (q - 1)^2": [lambda q: q - 1, lambda q: (q - 1) ** 2],
    "bias = c (q != 1)": [lambda q: (np.abs(q - 1) > 1e-12).astype(float)],
}


def table32(path):
    rows = yaml.safe_load(open(path))["materials_at_30cm"]
    white = next(r for r in rows if r["material"] == "white_paper")
    q = np.array([r["reflectance"] / white["reflectance"] for r in rows])
    y = np.array([r["mean_cm"] - white["mean_cm"] for r in rows])
    anchor = np.array([r["material"] == "white_paper" for r in rows])
    return q, y, anchor


def design(fs, q):
    return np.column_stack([f(q) for f in fs])


def loo_sklearn(fs, q, y, anchor):
    """Each non-anchor surface predicted by a no-intercept regression on the other eight."""
    x = design(fs, q)
    res = []
    for train, test in LeaveOneOut().split(x):
        if anchor[test[0]]:
            continue
        m = LinearRegression(fit_intercept=False).fit(x[train], y[train])
        res.append(y[test[0]] - m.predict(x[test])[0])
    return float(np.sqrt(np.mean(np.square(res))))


def main():
    q, y, anchor = table32(sys.argv[1])
    report = json.load(open(sys.argv[2]))["table32"]
    n = int((~anchor).sum())
    bad = []
    scores = {}
    for h in report["hypotheses"]:
        fs = FORMS.get(h["form"])
        if fs is None:
            continue  # the grid family (trapping) is checked by the C++ tests
        loo = loo_sklearn(fs, q, y, anchor)
        params = np.linalg.lstsq(design(fs, q), y, rcond=None)[0]
        if abs(loo - h["loo_rmse_cm"]) > 1e-6:
            bad.append(f"{h['form']}: leave-one-out {h['loo_rmse_cm']} here {loo}")
        if not np.allclose(params, h["params"][: len(params)], rtol=1e-6, atol=1e-9):
            bad.append(f"{h['form']}: parameters {h['params']} here {params.tolist()}")
        scores[h["form"]] = loo * math.sqrt(n / (n - len(fs)))
    chosen = report["hypotheses"][report["best"]]
    mine = min(scores, key=scores.get)
    if chosen["form"] in scores and chosen["form"] != mine:
        bad.append(f"chosen {chosen['form']}, here {mine}")
    print(f"checked {len(scores)} forms; chosen {chosen['form']}: leave-one-out {chosen['loo_rmse_cm']:.3f} cm")
    for b in bad:
        print("MISMATCH", b)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
