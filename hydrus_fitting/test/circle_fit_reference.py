# SPDX-License-Identifier: Apache-2.0
"""Independent circle fits for hydrus_fitting's circle_fit_reference_test.

Reads a CSV of points (case,x,y), fits every case with published
implementations: Kasa (scikit-image's CircleModel: least squares on
x^2 + y^2 = 2 cx x + 2 cy y + c, radius from the mean squared distance,
which is Kasa's), and circle-fit's Pratt, Taubin and Hyper (SVD forms, after
N. Chernov's MATLAB code) and its geometric Levenberg-Marquardt fit (Chernov's
LM.m, started from its Hyper fit). Writes case,method,cx,cy,r.

usage: circle_fit_reference.py POINTS.csv OUT.csv
"""
import csv
import sys
import warnings
from collections import OrderedDict

import numpy as np
from circle_fit import hyperSVD, lm, prattSVD, taubinSVD
from skimage.measure import CircleModel


def fits(xy):
    out = OrderedDict()
    kasa = CircleModel.from_estimate(xy)
    if kasa:
        out["kasa"] = (kasa.center[0], kasa.center[1], kasa.radius)
    for name, f in (("pratt", prattSVD), ("taubin", taubinSVD), ("hyper", hyperSVD)):
        out[name] = f(xy)[:3]
    start = np.array(out["hyper"], dtype=float)
    out["geometric"] = lm(xy, start, iter_max=200, epsilon=1e-14)[:3]
    return out


def main(points_path, out_path):
    cases = OrderedDict()
    with open(points_path) as f:
        for row in csv.DictReader(f):
            cases.setdefault(row["case"], []).append((float.fromhex(row["x"]), float.fromhex(row["y"])))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # circle-fit warns on its own iteration limits; the test judges the result
        with open(out_path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["case", "method", "cx", "cy", "r"])
            for case, pts in cases.items():
                for method, (cx, cy, r) in fits(np.array(pts)).items():
                    w.writerow([case, method, float(cx).hex(), float(cy).hex(), float(r).hex()])


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
