#!/usr/bin/python3
"""Compares result files bit for bit, leaving out what describes the run rather than its results.

    same_results.py A.h5 B.h5          # two files
    same_results.py DIR_A DIR_B        # every *.h5 of DIR_A against the same name in DIR_B

Every group, dataset and attribute must exist in both with the same type, shape and bytes,
except /meta's date, wall_time, threads, git_commit and compiler (they describe the run and the
build, not the result). NaN padding compares equal to NaN padding (bytes are compared, not
values). Exit 0 when all files are the same, 1 otherwise (each difference printed), 2 on usage.
For restructurings that must not change what a run computes.
"""
import os
import sys

import h5py
import numpy as np

RUN_ONLY = {"/meta": {"date", "wall_time", "threads", "git_commit", "compiler"}}


def _attrs(obj, path, out):
    skip = RUN_ONLY.get(path, set())
    for key, value in obj.attrs.items():
        if key not in skip:
            out[f"{path}@{key}"] = value


def _walk(f):
    items = {}
    _attrs(f, "/", items)

    def visit(name, obj):
        path = "/" + name
        _attrs(obj, path, items)
        if isinstance(obj, h5py.Dataset):
            items[path] = obj[()]

    f.visititems(visit)
    return items


def _same(a, b):
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape or a.dtype != b.dtype:
            return False
        if a.dtype.kind == "O":
            return all(x == y for x, y in zip(a.ravel(), b.ravel()))
        return a.tobytes() == b.tobytes()
    if isinstance(a, float) and isinstance(b, float):
        return np.float64(a).tobytes() == np.float64(b).tobytes()
    return type(a) is type(b) and a == b


def compare(file_a, file_b):
    with h5py.File(file_a, "r") as fa, h5py.File(file_b, "r") as fb:
        a, b = _walk(fa), _walk(fb)
    problems = [f"only in {file_a}: {k}" for k in sorted(a.keys() - b.keys())]
    problems += [f"only in {file_b}: {k}" for k in sorted(b.keys() - a.keys())]
    problems += [f"differs: {k}" for k in sorted(a.keys() & b.keys()) if not _same(a[k], b[k])]
    return problems


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    left, right = argv[1], argv[2]
    if os.path.isdir(left):
        names = sorted(n for n in os.listdir(left) if n.endswith(".h5"))
        pairs = [(os.path.join(left, n), os.path.join(right, n)) for n in names]
    else:
        pairs = [(left, right)]
    failed = 0
    for a, b in pairs:
        if not os.path.exists(b):
            print(f"missing: {b}")
            failed += 1
            continue
        problems = compare(a, b)
        print(f"{'same' if not problems else 'DIFFERENT'}: {os.path.basename(a)}")
        for p in problems[:20]:
            print("   ", p)
        failed += bool(problems)
    print(f"{len(pairs) - failed} of {len(pairs)} files the same")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
