#!/usr/bin/env python3
"""Compare two run folders bit for bit: every number of summary.json (wall and stage times
excepted, which measure the machine) and every dataset and attribute of run.h5.
Usage: compare-runs.py DIR_A DIR_B   (exit 1 and the differences listed when they differ)."""
import json
import sys

import h5py
import numpy as np

SKIP = {"wall_time_s", "stage_times_s"}


def flat(v, path=""):
    if isinstance(v, dict):
        out = {}
        for k, x in v.items():
            if k in SKIP:
                continue
            out.update(flat(x, f"{path}/{k}"))
        return out
    if isinstance(v, list):
        out = {}
        for i, x in enumerate(v):
            out.update(flat(x, f"{path}[{i}]"))
        return out
    return {path: v}


def h5(path):
    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                out[name] = obj[()]
            for k, a in obj.attrs.items():
                out[f"{name}@{k}"] = a
        f.visititems(visit)
        for k, a in f.attrs.items():
            out[f"@{k}"] = a
    return out


def same(a, b):
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape or a.dtype != b.dtype:
            return False
        if a.dtype.kind == "f":
            return a.tobytes() == b.tobytes()
        return np.array_equal(a, b)
    return a == b


def main(a, b):
    bad = []
    sa = flat(json.load(open(f"{a}/summary.json")))
    sb = flat(json.load(open(f"{b}/summary.json")))
    for k in sorted(set(sa) | set(sb)):
        if k not in sa or k not in sb:
            bad.append(f"summary {k}: only in {'b' if k not in sa else 'a'}")
        elif sa[k] != sb[k]:
            bad.append(f"summary {k}: {sa[k]!r} vs {sb[k]!r}")
    ha, hb = h5(f"{a}/run.h5"), h5(f"{b}/run.h5")
    for k in sorted(set(ha) | set(hb)):
        if k not in ha or k not in hb:
            bad.append(f"run.h5 {k}: only in {'b' if k not in ha else 'a'}")
        elif not same(ha[k], hb[k]):
            bad.append(f"run.h5 {k}: differs")
    print(f"{len(sa)} summary numbers, {len(ha)} run.h5 datasets/attributes compared")
    for x in bad:
        print(x)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
