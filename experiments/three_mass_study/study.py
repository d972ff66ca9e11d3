"""A bifurcation study end to end, from Python (the README's section; the same runs as
run_study.sh, as a notebook would make them, cell by cell).

    PYTHONPATH=build/release/python /usr/bin/python3 experiments/three_mass_study/study.py [OUT_DIR]

The chain: three unit masses and springs, dampers 0.05, a stop below mass 0 and a clearance
between masses 1 and 2 (r = 0.8), forced on mass 2. Each run shows its progress; the figure goes
to OUT_DIR (default docs/figures/three_mass_study, as three_mass_study.png) and the numbers are
printed.
"""
import os
import sys

import vibro

here = os.path.dirname(os.path.abspath(__file__))
root = os.path.dirname(os.path.dirname(here))
out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(root, "docs/figures/three_mass_study")
sys.path.insert(0, here)
import figures  # noqa: E402  (the drawing shared with run_study.sh)

# %% 1. Continuation in Ω with branch switching at the period doublings (each branch once).
results = {"continuation": vibro.continuation(os.path.join(root, "experiments/examples/three_mass_switching.yaml"))}
print(results["continuation"].summary.splitlines()[0])

# %% 2. The folds, period doublings and grazings followed in (Ω, forcing amplitude).
plane = os.path.join(here, "plane.yaml")
results["plane"] = vibro.continuation(plane) if os.path.isfile(plane) else None

# %% 3. A brute-force diagram, up and down, every value settled (or said not to be).
results["diagram"] = vibro.diagram(os.path.join(here, "diagram.yaml"), threads=2, progress=True)

# %% 4. The basins where the diagram's two sweeps end on different orbits.
results["basin"] = vibro.basin(os.path.join(here, "basin.yaml"), threads=2, progress=True)

# %% 5. The impact map where no period fits.
results["impact_map"] = vibro.simulate(os.path.join(here, "impact_map.yaml"))

# %% The figure and the numbers.
print(figures.draw(results, out))
print("\n".join(figures.summary(results)))
