"""Progress of every grid run kind: `vibro run` not on a terminal writes a compact line at each
tenth of the run; from Python, progress=True shows the same and a callable is given (done, total)."""
import re

import pytest
import vibro
from conftest import PAPER, write

DIAGRAM = PAPER + ("run: {kind: diagram, transient_periods: 2, diagram: {path: forcing.frequency, "
                   "values: [0.25, 0.26], transient: 1, points: 4, max_period: 2}}\n")
BASIN = PAPER + ("run: {kind: basin, transient_periods: 1, basin: {parameters: [{path: 'initial.x[0]', "
                 "linspace: [0.0, 0.003, 4]}, {path: 'initial.v[0]', linspace: [0.0, 0.003, 4]}], "
                 "max_period: 2, max_periods: 20}}\n")
LOCATE = PAPER + ("run: {kind: locate, transient_periods: 20, locate: {path: forcing.frequency, "
                  "linspace: [0.25, 0.26, 5], max_period: 2, max_periods: 50}}\n")
ORBIT = PAPER + "run: {kind: orbit, transient_periods: 4000, orbit: {period: 1}}\n"
SWEEP = PAPER + ("run: {kind: sweep, transient_periods: 0, periods: 1, sweep: {parameters: "
                 "[{path: forcing.frequency, linspace: [0.25, 0.26, 20]}]}}\n")
LYAPUNOV = PAPER + ("run: {kind: lyapunov, lyapunov: {transient: 1, align: 1, periods: 2, path: forcing.frequency, "
                    "values: [0.25, 0.255, 0.26]}}\n")
LINE = re.compile(r"^vibro: (\w+) (\d+)/(\d+) (?:points|steps) \((\d+) %\), [0-9.e+-]+ (?:points|steps)/s, "
                  r"(about \d+ s left|done|time left unknown yet)$")


def progress_lines(stderr):
    return [LINE.match(line).groups() for line in stderr.splitlines() if line.startswith("vibro: ")]


def test_diagram_writes_a_line_per_tenth_when_not_on_a_terminal(tmp_path, cli):
    code, err = cli("run", write(tmp_path, "d.yaml", DIAGRAM), "-o", "d.h5")
    assert code == 0, err
    lines = progress_lines(err)
    # Two values, both directions: four points, each past a new tenth.
    assert [(kind, done, total, share) for kind, done, total, share, _ in lines] == [
        ("diagram", "1", "4", "25"), ("diagram", "2", "4", "50"), ("diagram", "3", "4", "75"),
        ("diagram", "4", "4", "100")]
    assert lines[-1][4] == "done"
    assert err.rstrip().endswith("Results in d.h5.")  # the summary still closes the output


@pytest.mark.parametrize("text, kind, total", [(SWEEP, "sweep", 20), (BASIN, "basin", 16), (LYAPUNOV, "lyapunov", 3)],
                         ids=["sweep", "basin", "lyapunov"])
def test_every_grid_kind_shows_at_most_ten_lines(tmp_path, cli, text, kind, total):
    code, err = cli("run", write(tmp_path, "s.yaml", text), "-o", "s.h5", "--threads", "2")
    assert code == 0, err
    lines = progress_lines(err)
    assert 1 <= len(lines) <= 10 and all(k == kind and int(t) == total for k, _, t, _, _ in lines)
    done = [int(d) for _, d, _, _, _ in lines]
    assert done == sorted(done) and done[-1] == total
    # One line per tenth passed: the tenths of consecutive lines differ.
    tenths = [10 * d // total for d in done]
    assert len(set(tenths)) == len(tenths)


def test_a_callable_is_given_done_and_total(tmp_path):
    calls = []
    r = vibro.basin(BASIN, progress=lambda done, total: calls.append((done, total)))
    assert r.status == "completed" and calls and calls[-1] == (16, 16)
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)
    calls.clear()
    vibro.sweep(SWEEP, progress=lambda done, total: calls.append((done, total)))
    assert calls[-1] == (20, 20)


def test_progress_true_shows_the_lines_and_a_failing_callable_stops_the_run(capfd):
    vibro.diagram(DIAGRAM, progress=True)
    err = capfd.readouterr().err
    assert [done for _, done, _, _, _ in progress_lines(err)] == ["1", "2", "3", "4"]

    def fail(done, total):
        raise RuntimeError(f"stop at {done} of {total}")
    with pytest.raises(RuntimeError, match="stop at"):
        vibro.sweep(SWEEP, progress=fail, threads=1)
    with pytest.raises(TypeError, match="progress: expected True, False, None or a callable"):
        vibro.diagram(DIAGRAM, progress="yes")


def test_locate_counts_grid_points_then_brackets(tmp_path, cli):
    code, err = cli("run", write(tmp_path, "l.yaml", LOCATE), "-o", "l.h5", "--threads", "1")
    assert code == 0, err
    lines = progress_lines(err)
    # Five grid points, then the four brackets between neighbours: nine steps, one line each
    # (every step passes a new tenth of nine).
    assert [(kind, int(done), int(total)) for kind, done, total, _, _ in lines] == [
        ("locate", d, 9) for d in range(1, 10)]
    calls = []  # the module samples the progress while it waits: the last call is the end
    vibro.locate(LOCATE, progress=lambda done, total: calls.append((done, total)))
    assert calls and calls[-1] == (9, 9) and all(total == 9 for _, total in calls)
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)


def test_orbit_reports_its_transient_in_periods():
    # The transient is reported by a watcher every 0.25 s: how many calls come depends on the
    # machine's speed, never what they say (periods done of the transient's 4000, increasing).
    calls = []
    r = vibro.orbit(ORBIT, progress=lambda done, total: calls.append((done, total)))
    assert r.status == "completed"
    assert all(total == 4000 and 0 <= done <= total for done, total in calls)
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)
