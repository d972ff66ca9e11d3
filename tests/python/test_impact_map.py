"""The impact map (record.impact_map, docs/results.md /impact_map): the state just before every
impact, on both engines, in simulations and sweeps; read back against the event log of the same
run and against the geometry of the stops."""
import math

import numpy as np
import pytest
import vibro
from conftest import SOURCE

# The paper's system (Wagg 2004, fig. 2) at Ω = 0.255: impacts on both stops, chatter and sticking.
BASE = (SOURCE / "experiments/wagg2004/fig2_sticking_orbit.yaml").read_text().split("\nrecord:")[0]
SCENE = BASE + ("\nrecord: {events: true, impact_map: true}\n"
                "run: {kind: simulate, transient_periods: 20, periods: 6}\n")
OMEGA = 0.255
LOWER, UPPER = -0.3, 0.1  # stop 0 below mass 0, stop 1 above mass 1


@pytest.mark.parametrize("engine", ["dense", "modal"])
def test_one_row_per_impact_with_the_state_on_its_stop(engine):
    r = vibro.simulate(SCENE + f"solver: {{engine: {engine}}}\n")
    impacts = r.events.kind == 0
    m = r.impact_map
    assert len(m.t) == impacts.sum() > 10
    # The same impacts as the event log, in the same order, with the same approach speed.
    assert np.array_equal(m.t, r.events.t[impacts]) and np.array_equal(m.stop, r.events.stop[impacts])
    assert np.array_equal(m.velocity, r.events.v_before[impacts]) and (m.velocity > 0).all()
    assert np.allclose(m.phase, np.mod(OMEGA * m.t, 2 * math.pi), rtol=0, atol=1e-12)
    assert ((m.phase >= 0) & (m.phase < 2 * math.pi)).all()
    # The state is on the stop (the trigger tolerance is 1e-12 of L = O(1)) and moving into it
    # at the recorded speed: the gap rate of stop 0 (x0 ≥ −0.3) is −v0, of stop 1 (x1 ≤ 0.1) v1.
    on0, on1 = m.stop == 0, m.stop == 1
    assert on0.any() and on1.any()
    assert np.abs(m.x[on0, 0] - LOWER).max() < 1e-9 and np.abs(m.x[on1, 1] - UPPER).max() < 1e-9
    assert np.allclose(-m.v[on0, 0], m.velocity[on0], rtol=1e-9, atol=1e-12)
    assert np.allclose(m.v[on1, 1], m.velocity[on1], rtol=1e-9, atol=1e-12)


def test_both_engines_give_the_same_map():
    dense = vibro.simulate(SCENE + "solver: {engine: dense}\n").impact_map
    modal = vibro.simulate(SCENE + "solver: {engine: modal}\n").impact_map
    assert np.array_equal(dense.stop, modal.stop)
    # Two exact flows computed differently: they agree to rounding grown over 26 periods of
    # impacts and chatter (the engines' own comparison in tests/io/test_engine.cpp uses 1e-9). An
    # impact time is conditioned by 1/g' (a chatter's late bounces arrive at 1e-5 of the speeds):
    # its error is measured by the gap it implies, |Δt| g', to rounding of L = O(1); the times of
    # impacts faster than 1e-3 to 1e-10 (measured: 3.4e-14, 9.9e-12; states 2.2e-10).
    dt = np.abs(dense.t - modal.t)
    assert (dt * dense.velocity).max() < 1e-12
    assert dt[dense.velocity > 1e-3].max() < 1e-10
    assert np.abs(dense.x - modal.x).max() < 1e-9


def test_a_sweep_stacks_the_map_point_by_point():
    scene = vibro.Scene.from_text(SCENE)
    r = vibro.sweep(scene, {"forcing.frequency": [0.255, 0.27]}, threads=2)
    for p, omega in enumerate([0.255, 0.27]):
        rows = r.point_rows("impact_map", p)
        scene.set("forcing.frequency", omega)
        alone = vibro.simulate(scene).impact_map
        assert np.array_equal(rows["t"], alone.t) and np.array_equal(rows["x"], alone.x)


def test_a_scene_without_it_has_no_group():
    r = vibro.simulate(BASE + "\nrecord: {events: true}\nrun: {kind: simulate, transient_periods: 2, periods: 2}\n")
    with pytest.raises((AttributeError, KeyError)):
        r.impact_map


def test_a_diagram_records_the_map_of_every_value_it_records():
    P = 8
    r = vibro.diagram(BASE + "\nrecord: {impact_map: true}\nrun: {kind: diagram, transient_periods: 30, diagram: "
                             "{path: forcing.frequency, linspace: [0.25, 0.26, 5], points: %d, max_period: 4, "
                             "transient: 20}}\n" % P)
    m, d = r.impact_map, r.diagram
    assert set(m.direction) == {0, 1} and r.impact_map.labels("direction")["names"] == ["up", "down"]
    for direction, name in enumerate(["up", "down"]):
        for g, omega in enumerate(d.parameter):
            rows = (m.direction == direction) & (m.point == g)
            # Every impact of the P recorded periods, no more: the diagram's own count of them.
            assert rows.sum() == round(d[f"impacts_{name}"][g] * P) > 0
            t = m.t[rows]
            assert (np.diff(t) > 0).all()
            assert np.allclose(m.phase[rows], np.mod(omega * t, 2 * math.pi), rtol=0, atol=1e-9)
            on0, on1 = rows & (m.stop == 0), rows & (m.stop == 1)
            assert np.abs(m.x[on0, 0] - LOWER).max(initial=0) < 1e-9 and np.abs(m.x[on1, 1] - UPPER).max(initial=0) < 1e-9
    assert (m.velocity > 0).all()


def test_a_continuation_records_the_map_of_every_branch_point():
    cascade = (SOURCE / "experiments/examples/pd_cascade.yaml").read_text().split("\nrun:")[0]
    r = vibro.continuation(cascade + "\nrecord: {impact_map: true}\nrun: {kind: continue, transient_periods: 300, "
                                     "continue: {path: forcing.frequency, range: [1.66, 1.74], max_doublings: 1}}\n")
    m, b = r.impact_map, r.branch
    assert set(b.k) == {1, 2}
    # Each point's orbit over kT: its impacts are the signature's (no chatter on these orbits),
    # in time order over one period kT from the section, each on the stop x1 ≤ 0.
    assert (b.signature[:, 1] == 0).all()
    counts = np.bincount(m.point, minlength=b.p.size)
    assert np.array_equal(counts, b.signature[:, 0].astype(int))
    for i in range(0, b.p.size, 7):
        t = m.t[m.point == i]
        assert (np.diff(t) > 0).all() and t.min() >= b.t0[i] and t.max() <= b.t0[i] + b.k[i] * 2 * math.pi / b.p[i]
        assert np.allclose(m.phase[m.point == i], np.mod(b.p[i] * t, 2 * math.pi), rtol=0, atol=1e-9)
    assert np.abs(m.x[:, 1]).max() < 1e-9 and (m.velocity > 0).all()
