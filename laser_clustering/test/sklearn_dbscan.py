#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Runs scikit-learn's DBSCAN on the cases written by dbscan_sklearn_test.

Input (text, one case after another):
    case <name> <n> <dim> <eps as float.hex> <min_samples>
    <n lines of dim hex floats>
Output (text, per case):
    case <name>
    labels <n ints>
    core <ascending indices of core samples>

Hex floats carry the coordinates exactly, so both sides cluster the very
same numbers. The tree algorithm is pinned to kd_tree: its leaf test is
"sum of squared differences <= eps*eps", the rule tinyline's DBSCAN
documents (the 'brute' algorithm computes distances with a dot-product
expansion that rounds differently at ties).
"""
import sys

import numpy as np
from sklearn.cluster import DBSCAN


def read_cases(path):
    with open(path) as f:
        lines = f.read().split("\n")
    i = 0
    while i < len(lines):
        head = lines[i].split()
        i += 1
        if not head:
            continue
        if head[0] != "case" or len(head) != 6:
            raise SystemExit(f"{path}:{i}: expected 'case <name> <n> <dim> <eps> <min_samples>', got {lines[i-1]!r}")
        name, n, dim, eps, min_samples = head[1], int(head[2]), int(head[3]), float.fromhex(head[4]), int(head[5])
        pts = np.empty((n, dim), dtype=np.float64)
        for k in range(n):
            vals = lines[i].split()
            if len(vals) != dim:
                raise SystemExit(f"{path}:{i+1}: case {name}: expected {dim} values, got {len(vals)}")
            pts[k] = [float.fromhex(v) for v in vals]
            i += 1
        yield name, pts, eps, min_samples


def main():
    if len(sys.argv) != 3:
        raise SystemExit("usage: sklearn_dbscan.py <cases.txt> <labels.txt>")
    out = []
    for name, pts, eps, min_samples in read_cases(sys.argv[1]):
        model = DBSCAN(eps=eps, min_samples=min_samples, algorithm="kd_tree", leaf_size=8).fit(pts)
        out.append(f"case {name}")
        out.append("labels " + " ".join(str(int(v)) for v in model.labels_))
        out.append("core " + " ".join(str(int(v)) for v in np.sort(model.core_sample_indices_)))
    with open(sys.argv[2], "w") as f:
        f.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
