#!/usr/bin/env python3
"""A five-mass chain built from numpy, swept in frequency, its sticking fractions plotted.

    PYTHONPATH=build/release/python python3 tools/examples/chain_sweep.py [OUTDIR]

The chain: five unit masses, unit springs from a wall to mass 0 and between neighbours, the end
mass free, dampers 0.1 beside every spring (C = 0.1 K), forced by 0.5 cos(Ωt) on mass 0. A stop
below mass 0 at -0.3 and one above mass 4 at 0.3, both r = 0.7. For each Ω of the sweep: 100
forcing periods of transient, then 10 recorded periods; the plot shows the mean fraction of the
period each stop holds its mass. Writes OUTDIR/chain_sweep.png (OUTDIR: a new temporary folder
if not given) and prints a line per frequency. Run by ctest ("python: example chain_sweep").
"""
import pathlib
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402 (after the backend is chosen)
import numpy as np  # noqa: E402

import vibro  # noqa: E402

n = 5
K = 2 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1)
K[-1, -1] = 1.0  # the end mass has one spring
scene = vibro.Scene.from_matrices(
    np.eye(n), 0.1 * K, K, frequency=0.1, cosine=[0.5, 0, 0, 0, 0],
    stops=[{"mass": 0, "side": "lower", "position": -0.3, "restitution": 0.7, "name": "below mass 0"},
           {"mass": 4, "side": "upper", "position": 0.3, "restitution": 0.7, "name": "above mass 4"}],
    run={"transient_periods": 100, "periods": 10}, name="five-mass chain")

omega = np.linspace(0.05, 0.3, 41)
result = vibro.sweep(scene, {"forcing.frequency": omega}, statistics=True)  # only what is plotted
if not np.all(result.sweep.status == 0):
    sys.exit(f"points stopped early: {result.sweep.status}")
fraction = result.stats.sticking_fraction.mean(axis=1)  # points × periods × stops → points × stops
stops = result.stats.labels("sticking_fraction")["stops"]
for w, row in zip(result.sweep.values[:, 0], fraction):
    print(f"Ω = {w:.4f}: " + ", ".join(f"{name} {f:.4f}" for name, f in zip(stops, row)))

figure, axes = plt.subplots(figsize=(6, 3.2))
for j, name in enumerate(stops):
    axes.plot(result.sweep.values[:, 0], fraction[:, j], "o-", ms=3, label=name)
axes.set_xlabel(r"forcing frequency $\Omega$")
axes.set_ylabel("fraction of the period stuck")
axes.set_title(f"{scene.name}: {result.meta['sticks']} sticks in {len(omega)} runs", fontsize=9)
axes.legend()
figure.tight_layout()
outdir = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else tempfile.mkdtemp(prefix="vibro-example-"))
outdir.mkdir(parents=True, exist_ok=True)
figure.savefig(outdir / "chain_sweep.png", dpi=120)
print(f"wrote {outdir / 'chain_sweep.png'}")
