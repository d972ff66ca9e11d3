"""The run kinds as the module sees them: the table `vibro run` dispatches on (vibro.run_kinds()),
and runs of one kind on a scene written for another (the wrapper replaces the run section)."""
import pytest
import vibro
from conftest import PAPER

# The paper's scene with each kind's own run section (small grids: the loader checks every value).
RUNS = {
    "diagram": "run: {kind: diagram, transient_periods: 2, diagram: {path: forcing.frequency, "
               "linspace: [0.25, 0.26, 2], transient: 1, points: 4, max_period: 2}}\n",
    "basin": "run: {kind: basin, basin: {parameters: [{path: 'initial.x[0]', linspace: [0.0, 0.001, 2]}, "
             "{path: 'initial.v[0]', linspace: [0.0, 0.001, 2]}], max_period: 2, max_periods: 20}}\n",
    "lyapunov": "run: {kind: lyapunov, lyapunov: {transient: 1, align: 1, periods: 2}}\n",
    "orbit": "run: {kind: orbit, transient_periods: 5, orbit: {period: 1}}\n",
    "locate": "run: {kind: locate, transient_periods: 5, locate: {path: forcing.frequency, "
              "linspace: [0.25, 0.26, 2], max_periods: 100}}\n",
}


def test_run_kinds_are_the_commands():
    kinds = vibro.run_kinds()
    assert list(kinds) == ["simulate", "sweep", "locate", "continue", "basin", "diagram", "lyapunov", "orbit"]
    assert all(isinstance(s, str) and s for s in kinds.values())


@pytest.mark.parametrize("kind", sorted(RUNS))
def test_simulate_a_scene_written_for_another_kind(kind):
    scene = vibro.Scene.from_text(PAPER + RUNS[kind])
    result = vibro.simulate(scene, periods=1, transient_periods=0)
    assert result.status == "completed"
    assert result.scene.attrs["run_kind"] == "simulate"
    swept = vibro.sweep(scene, {"forcing.frequency": [0.25, 0.26]}, periods=1, transient_periods=0, record={})
    assert swept.scene.attrs["run_kind"] == "sweep"
