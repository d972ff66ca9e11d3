#!/usr/bin/env python3
"""Reads a vibro result file with h5py and checks it against docs/results.md.

    python3 tests/io/read_back.py out.h5                      # print the tree, check the layout
    python3 tests/io/read_back.py out.h5 --dof 2 --stops 2 --samples 32 --periods 4 [--points 5]

Checks: /scene and /meta are there with their attributes; the columns of every recorded group
agree in length; shapes follow the layout (a sweep adds a leading point axis to samples,
poincare and stats, and a `point` column to events and contacts); every value that is not
padding is finite; enumerations are in range. The optional numbers check sizes exactly.
Exit status 0 if the file is correct, 1 with one line per problem otherwise.
"""
import argparse
import sys

import h5py
import numpy as np

PROBLEMS = []


def check(condition, message):
    if not condition:
        PROBLEMS.append(message)
    return condition


def text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def print_tree(f):
    def show(name, obj):
        if isinstance(obj, h5py.Dataset):
            print(f"  /{name:32s} {str(obj.dtype):8s} {obj.shape}")
        else:
            print(f"  /{name}/")
    print(f"{f.filename}:")
    f.visititems(show)
    meta = f["meta"].attrs
    print("  meta: " + ", ".join(f"{k}={text(meta[k])}" for k in
                                 ("version", "git_commit", "date", "status", "threads")
                                 if k in meta))


def check_scene(f, dof, stops):
    scene = f["scene"]
    for name in ("yaml", "file", "frequency", "period", "periods"):
        check(name in scene.attrs, f"/scene: attribute {name} missing")
    engine = text(f["meta"].attrs.get("engine", "dense"))
    if engine == "modal":  # the chain in banded form (docs/results.md)
        n = scene["mass_diagonal"].shape[0]
        check(dof is None or n == dof, f"/scene/mass_diagonal: {n} DOF, expected {dof}")
        check(scene["stiffness_diagonal"].shape == (n,), "/scene/stiffness_diagonal: shape")
        check(scene["stiffness_off_diagonal"].shape == (n - 1,), "/scene/stiffness_off_diagonal: shape")
        check(scene["rayleigh"].shape == (2,), "/scene/rayleigh: shape")
    else:
        n = scene["mass"].shape[0]
        check(dof is None or n == dof, f"/scene/mass: {n} DOF, expected {dof}")
        for name in ("mass", "damping", "stiffness"):
            check(scene[name].shape == (n, n), f"/scene/{name}: shape {scene[name].shape}")
    for name in ("forcing_constant", "forcing_cosine", "forcing_sine", "x0", "v0"):
        check(scene[name].shape == (n,), f"/scene/{name}: shape {scene[name].shape}")
    m = scene["stop_kind"].shape[0]
    check(stops is None or m == stops, f"/scene/stop_kind: {m} stops, expected {stops}")
    for name in ("stop_mass", "stop_other", "stop_position", "stop_restitution",
                 "stop_amplitude", "stop_phase", "stop_name"):
        check(scene[name].shape == (m,), f"/scene/{name}: shape {scene[name].shape}")
    check(list(scene["stop_kind"].attrs["names"]) == ["upper", "lower", "between"],
          "/scene/stop_kind: names")
    return n, m


def check_meta(f):
    meta = f["meta"].attrs
    for name in ("version", "git_commit", "date", "compiler", "threads", "trigger",
                 "chatter_height", "simultaneity", "max_events", "contact_sets_built",
                 "sticking_flows_built", "wall_time", "impacts", "sticks", "releases",
                 "chatters", "segments", "status", "message"):
        check(name in meta, f"/meta: attribute {name} missing")
    check(text(meta.get("status", "")) in ("completed", "event_cap", "numerical_failure",
                                           "points_stopped_early"),
          f"/meta: status {meta.get('status')!r} (a finished file is never 'running')")


def valid_rows(group, points):
    """Rows of each point that hold data (the rest of a stacked array is padding)."""
    if points is None:
        return None
    rows = group["rows"][()]
    check(rows.shape == (points,), f"{group.name}/rows: shape {rows.shape}")
    return rows


def check_ragged(f, name, columns, points):
    if name not in f:
        return
    g = f[name]
    lengths = {c: g[c].shape for c in columns}
    r = g[columns[0]].shape[0]
    check(all(s == (r,) for s in lengths.values()), f"/{name}: column lengths {lengths}")
    for c in columns:
        if g[c].dtype.kind == "f":
            check(np.isfinite(g[c][()]).all(), f"/{name}/{c}: values that are not finite")
    if points is not None:
        point = g["point"][()]
        rows = valid_rows(g, points)
        check(point.shape == (r,), f"/{name}/point: shape {point.shape}")
        check((np.diff(point) >= 0).all(), f"/{name}/point: not in point order")
        check((np.bincount(point, minlength=points) == rows).all(),
              f"/{name}: point column disagrees with rows")


def check_stacked(f, name, columns, points, rows_expected, cols):
    """columns: {dataset: number of columns, or 0 for a 1-D column per point}."""
    if name not in f:
        return
    g = f[name]
    lead = () if points is None else (points,)
    r = g[next(iter(columns))].shape[len(lead)]
    check(rows_expected is None or r == rows_expected,
          f"/{name}: {r} rows per point, expected {rows_expected}")
    rows = valid_rows(g, points)
    for c, width in columns.items():
        want = lead + (r,) + ((cols[width],) if width else ())
        check(g[c].shape == want, f"/{name}/{c}: shape {g[c].shape}, expected {want}")
        data = g[c][()]
        if points is None:
            valid = [data]
        else:
            valid = [data[p, :rows[p]] for p in range(points)]
        for block in valid:
            if data.dtype.kind == "f":
                check(np.isfinite(block).all(), f"/{name}/{c}: values that are not finite")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file")
    parser.add_argument("--dof", type=int)
    parser.add_argument("--stops", type=int)
    parser.add_argument("--samples", type=int, help="samples per run")
    parser.add_argument("--periods", type=int, help="rows of /stats per run")
    parser.add_argument("--points", type=int, help="the file is a sweep of this many points")
    parser.add_argument("--quiet", action="store_true")
    args = parser.parse_args()

    with h5py.File(args.file, "r") as f:
        if not args.quiet:
            print_tree(f)
        for group in ("scene", "meta"):
            if not check(group in f, f"/{group} missing"):
                break
        else:
            n, m = check_scene(f, args.dof, args.stops)
            check_meta(f)
            points = None
            if "sweep" in f:
                sweep = f["sweep"]
                points = sweep["values"].shape[0]
                k = len(sweep.attrs["parameters"])
                check(sweep["values"].shape == (points, k), "/sweep/values: shape")
                check(list(sweep["values"].attrs["parameters"]) == list(sweep.attrs["parameters"]),
                      "/sweep/values: parameters attribute")
                check(int(sweep.attrs["completed"]) == points == int(sweep.attrs["points"]),
                      "/sweep: completed and points disagree with /sweep/values")
                check(set(np.unique(sweep["status"][()])) <= {0, 1, 2}, "/sweep/status: values")
                for name, shape in (("status", (points,)), ("t_end", (points,)),
                                    ("x_end", (points, n)), ("v_end", (points, n)),
                                    ("counts", (points, 7))):
                    check(sweep[name].shape == shape, f"/sweep/{name}: shape {sweep[name].shape}")
                check(np.isfinite(sweep["values"][()]).all(), "/sweep/values: not finite")
            check(args.points is None or points == args.points,
                  f"{points} sweep points, expected {args.points}")
            check_ragged(f, "events", ["t", "stop", "kind", "v_before", "v_after", "force"],
                         points)
            if "events" in f:
                kind = f["events/kind"]
                check(list(kind.attrs["names"]) ==
                      ["impact", "stick", "release", "chatter-limit"], "/events/kind: names")
                check(((kind[()] >= 0) & (kind[()] <= 3)).all(), "/events/kind: out of range")
                check(((f["events/stop"][()] >= 0) & (f["events/stop"][()] < m)).all(),
                      "/events/stop: out of range")
            check_ragged(f, "contacts",
                         ["stop", "t_start", "t_end", "force_min", "t_force_min", "closed"], points)
            cols = {1: n, 2: m}
            for name in ("samples", "poincare"):
                check_stacked(f, name, {"t": 0, "x": 1, "v": 1}, points,
                              args.samples if name == "samples" else None, cols)
            check_stacked(f, "stats", {"sticking_fraction": 2, "impacts": 2}, points,
                          args.periods, cols)

    for problem in PROBLEMS:
        print(f"{args.file}: {problem}", file=sys.stderr)
    if not args.quiet and not PROBLEMS:
        print("layout ok")
    return 1 if PROBLEMS else 0


if __name__ == "__main__":
    sys.exit(main())
