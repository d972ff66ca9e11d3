"""Shared helpers of the Python module's tests (tests/python; run by ctest, see CMakeLists.txt).

ctest sets PYTHONPATH to the build's python folder, VIBRO_CLI to the `vibro` command and
VIBRO_SOURCE to the repository. Each test writes only below its own tmp_path.
"""
import os
import pathlib
import subprocess

import h5py
import numpy as np
import pytest

SOURCE = pathlib.Path(os.environ.get("VIBRO_SOURCE", pathlib.Path(__file__).resolve().parents[2]))
CLI = os.environ.get("VIBRO_CLI", str(SOURCE / "build/release/tools/vibro/vibro"))

# The paper's system (Wagg 2004, fig. 2) at Ω = 0.255, which impacts, chatters, sticks and
# releases: the scene file's model, forcing, stops and initial state, with a record of our own.
PAPER = (SOURCE / "experiments/wagg2004/fig2_sticking_orbit.yaml").read_text().split("\nrecord:")[0] + (
    "\nrecord: {events: true, contacts: true, statistics: true, poincare: true, samples: {per_period: 50}}\n")

# Attributes that describe a run rather than its results (as in tests/io/test_mpi_sweep.py).
RUN_ATTRIBUTES = {("/meta", "date"), ("/meta", "wall_time"), ("/meta", "threads")}


@pytest.fixture
def cli(tmp_path):
    """Runs the `vibro` command in tmp_path; returns (exit code, stderr)."""
    def run(*args):
        done = subprocess.run([CLI, *map(str, args)], cwd=tmp_path, capture_output=True, text=True, timeout=240)
        return done.returncode, done.stderr
    return run


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def same_bits(a, b):
    """Equal shape, dtype and every byte (NaN padding included)."""
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype.kind in "OSU" or b.dtype.kind in "OSU":
        return a.shape == b.shape and [str(x) for x in a.ravel()] == [str(x) for x in b.ravel()]
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def file_tree(path):
    """{dataset path: array} and {(object, attribute): value} of an HDF5 file, read by h5py."""
    datasets, attributes = {}, {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            key = "/" + name
            if isinstance(obj, h5py.Dataset):
                datasets[key] = obj.asstr()[()] if h5py.check_string_dtype(obj.dtype) else obj[()]
            for a, v in obj.attrs.items():
                attributes[(key, a)] = v
        f.visititems(visit)
        for a, v in f.attrs.items():
            attributes[("/", a)] = v
    return datasets, attributes


def attribute_equal(a, b):
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype.kind in "OSU":
        return [str(x) for x in a.ravel()] == [str(x) for x in b.ravel()]
    return same_bits(a, b)


def differences(file_a, file_b, ignore_attributes=frozenset()):
    """Everything that differs between two result files, beyond RUN_ATTRIBUTES and `ignore`."""
    da, aa = file_tree(file_a)
    db, ab = file_tree(file_b)
    out = []
    if set(da) != set(db):
        out.append(f"datasets differ: {sorted(set(da) ^ set(db))}")
    out += [f"{k}: data differ" for k in sorted(set(da) & set(db)) if not same_bits(da[k], db[k])]
    skip = RUN_ATTRIBUTES | set(ignore_attributes)
    keys_a, keys_b = set(aa) - skip, set(ab) - skip
    if keys_a != keys_b:
        out.append(f"attributes differ: {sorted(keys_a ^ keys_b)}")
    out += [f"attribute {k}: {aa[k]!r} != {ab[k]!r}" for k in sorted(keys_a & keys_b) if not attribute_equal(aa[k], ab[k])]
    return out


def result_differences(result, path):
    """Datasets of a vibro.Result against a file's, bit for bit (the arrays as Python sees them)."""
    data, _ = file_tree(path)
    out = []
    if set(result.datasets()) != set(data):
        out.append(f"datasets differ: {sorted(set(result.datasets()) ^ set(data))}")
    out += [f"{k}: data differ" for k in sorted(set(result.datasets()) & set(data)) if not same_bits(result[k], data[k])]
    return out
