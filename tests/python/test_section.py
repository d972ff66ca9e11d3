"""Poincaré sections on a hyperplane (record.section, docs/results.md /section): read back through
the reader on both engines, a sweep's rows point by point, the scene's section kept by the record
keywords, and vibro.plot.section drawing the stored data."""
import math

import numpy as np
import pytest
import vibro
import vibro.plot
from conftest import SOURCE

# The paper's system (Wagg 2004, fig. 2) at Ω = 0.255: impacts on both stops, chatter and sticking.
BASE = (SOURCE / "experiments/wagg2004/fig2_sticking_orbit.yaml").read_text().split("\nrecord:")[0]
SCENE = BASE + ("\nrecord: {section: {coordinate: 1, value: 0.0, direction: up}}\n"
                "run: {kind: simulate, transient_periods: 20, periods: 6}\n")
OMEGA = 0.255


@pytest.mark.parametrize("engine", ["dense", "modal"])
def test_each_row_is_an_upward_crossing_on_the_hyperplane(engine):
    s = vibro.simulate(SCENE + f"solver: {{engine: {engine}}}\n").section
    assert len(s.t) >= 6 and (np.diff(s.t) > 0).all()
    assert (s.direction == 1).all()
    # On the hyperplane x1 = 0 (located as an impact: to rounding of L = O(1)), moving up.
    assert np.abs(s.x[:, 1]).max() < 1e-12
    assert (s.v[:, 1] > 0).all()
    assert np.allclose(s.phase, np.mod(OMEGA * s.t, 2 * math.pi), rtol=0, atol=1e-12)


def test_both_engines_give_the_same_section():
    dense = vibro.simulate(SCENE + "solver: {engine: dense}\n").section
    modal = vibro.simulate(SCENE + "solver: {engine: modal}\n").section
    assert len(dense.t) == len(modal.t)
    # Two exact flows computed differently (their impact maps agree to 1e-10 in time,
    # tests/python/test_impact_map.py); these crossings are transversal (|x1'| ≥ 1e-2).
    assert np.abs(dense.t - modal.t).max() < 1e-9
    assert np.abs(dense.x - modal.x).max() < 1e-9


def test_a_sweep_concatenates_the_crossings_point_by_point():
    scene = vibro.Scene.from_text(SCENE)
    r = vibro.sweep(scene, {"forcing.frequency": [0.255, 0.27]}, threads=2)
    for p, omega in enumerate([0.255, 0.27]):
        rows = r.point_rows("section", p)
        scene.set("forcing.frequency", omega)
        alone = vibro.simulate(scene).section
        assert len(alone.t) > 0
        assert np.array_equal(rows["t"], alone.t) and np.array_equal(rows["x"], alone.x)


def test_record_keywords_keep_the_scene_section_and_plot_draws_it():
    scene = vibro.Scene.from_text(SCENE)
    assert scene.record["section"] == {"normal": [0.0, 1.0], "value": 0.0, "direction": "up"}
    r = vibro.simulate(scene, events=True)
    assert "section" in r and "events" in r
    ax = vibro.plot.section(r, 1, "v")
    phase, speed = ax.lines[0].get_data()
    assert np.array_equal(phase, r.section.phase) and np.array_equal(speed, r.section.v[:, 1])
    r2 = vibro.simulate(scene, section={"normal": [1, -1], "value": 0.05, "direction": "both"})
    d = r2.section.direction
    assert len(d) >= 2 and (np.diff(d) != 0).all()  # both directions: they alternate
