"""vibro.plot: each standard figure drawn from a result of its run kind (from memory and from the
file), checked against the data it shows, and refused with a ValueError for a result without the
group it needs."""
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import vibro  # noqa: E402
import vibro.plot  # noqa: E402
from conftest import SOURCE  # noqa: E402

BASE = (SOURCE / "experiments/wagg2004/fig2_sticking_orbit.yaml").read_text().split("\nrecord:")[0]
# The period-doubling cascade of experiments/examples/pd_cascade.yaml, over a short range: the
# first doubling (Ω ≈ 1.682) and the doubled branch's (≈ 1.7336).
CASCADE = (SOURCE / "experiments/examples/pd_cascade.yaml").read_text().split("\nrun:")[0]


def lines_data(ax):
    return [(np.asarray(l.get_xdata(), float), np.asarray(l.get_ydata(), float)) for l in ax.get_lines()]


def test_branch_marks_every_located_bifurcation_on_its_branch(tmp_path):
    r = vibro.continuation(CASCADE + "\nrun: {kind: continue, transient_periods: 300, continue: "
                           "{path: forcing.frequency, range: [1.66, 1.74], step: 0.01, max_step: 0.1, max_doublings: 1}}\n",
                           output=str(tmp_path / "c.h5"))
    assert r.bifurcations.p.size >= 2 and set(r.branch.k) == {1, 2}
    for source in (r, str(tmp_path / "c.h5")):
        ax = vibro.plot.branch(source, coordinate=0)
        drawn = lines_data(ax)
        # Every branch point at the fixed phase is on a drawn line, and every bifurcation has a marker
        # at its parameter on its branch's curve.
        xs = np.concatenate([x for x, _ in drawn])
        assert np.isin(r.branch.p[r.branch.fixed_ok == 1], xs).all()
        markers = [(x[0], y[0]) for (x, y), l in zip(drawn, ax.get_lines()) if l.get_linestyle() == "None"]
        assert len(markers) == r.bifurcations.p.size
        assert sorted(m[0] for m in markers) == pytest.approx(sorted(r.bifurcations.p), abs=1e-12)
        # Unstable stretches are dashed, stable solid.
        styles = {l.get_linestyle() for l in ax.get_lines() if l.get_linestyle() != "None"}
        assert styles <= {"-", "--"} and "-" in styles
        plt.close(ax.figure)
    # A palette colours the periods in turn (period 1 its first colour, period 2 its second).
    ax = vibro.plot.branch(r, palette=["black", "tab:green"], markers=False)
    colours = {l.get_label().split(",")[0]: matplotlib.colors.to_hex(l.get_color()) for l in ax.get_lines()
               if l.get_label().startswith("period")}
    assert colours == {"period 1T": matplotlib.colors.to_hex("black"), "period 2T": matplotlib.colors.to_hex("tab:green")}
    plt.close(ax.figure)


def test_diagram_lines_are_the_recorded_points():
    r = vibro.diagram(BASE + "\nrun: {kind: diagram, transient_periods: 50, diagram: "
                             "{path: forcing.frequency, linspace: [0.255, 0.26, 3], points: 4, max_period: 2, transient: 20}}\n")
    ax = vibro.plot.diagram(r, mass=0)
    (xu, yu), (xd, yd) = lines_data(ax)
    assert np.array_equal(yu, r.diagram.x_up[:, :, 0].ravel())
    assert np.array_equal(yd, r.diagram.x_down[:, :, 0].ravel())
    assert np.array_equal(xu, np.repeat(r.diagram.parameter, 4))
    plt.close(ax.figure)


def test_impact_map_basin_and_lyapunov_draw_their_data():
    sim = vibro.simulate(BASE + "\nrecord: {impact_map: true}\nrun: {kind: simulate, transient_periods: 10, periods: 5}\n")
    ax = vibro.plot.impact_map(sim, stop=1)
    (phase, speed), = lines_data(ax)
    on = sim.impact_map.stop == 1
    assert np.array_equal(phase, sim.impact_map.phase[on]) and np.array_equal(speed, sim.impact_map.velocity[on])
    assert ((phase >= 0) & (phase < 2 * math.pi)).all()
    plt.close(ax.figure)

    b = vibro.basin(BASE + "\nrun: {kind: basin, basin: {parameters: [{path: 'initial.x[0]', linspace: [-0.2, 0.05, 4]},"
                           " {path: 'initial.v[0]', linspace: [-0.1, 0.1, 4]}], max_periods: 200}}\n")
    ax = vibro.plot.basin(b)
    image = ax.get_images()[0].get_array()
    assert np.array_equal(np.asarray(image), np.clip(b.basin.label, -4, None) + 4)
    plt.close(ax.figure)

    ly = vibro.lyapunov(BASE + "\nrun: {kind: lyapunov, transient_periods: 20, lyapunov: {periods: 20}}\n")
    ax = vibro.plot.lyapunov(ly)
    heights = [p.get_height() for p in ax.patches]
    assert heights == pytest.approx(list(ly.lyapunov.exponents[0][ly.lyapunov.finite[0] == 1]), rel=0, abs=0)
    plt.close(ax.figure)


def test_a_result_without_the_group_is_refused_by_name():
    sim = vibro.simulate(BASE + "\nrun: {kind: simulate, periods: 1}\n")
    for draw, group in [(vibro.plot.branch, "branch"), (vibro.plot.diagram, "diagram"), (vibro.plot.plane, "curve"),
                        (vibro.plot.basin, "basin"), (vibro.plot.impact_map, "impact_map"),
                        (vibro.plot.lyapunov, "lyapunov")]:
        with pytest.raises(ValueError, match=f"the result has no /{group}"):
            draw(sim)
