"""Ctrl-C during a set-up that nothing can poll — the modes of a long modal chain, one LAPACK call
of seconds, which runs where the run still answers its stop flag within 10 ms
(framework/include/vibro/bounded_wait.hpp) — raises vibro.Interrupted from every run function,
never a bare RuntimeError, and soon after the signal.

Each case runs a scene of the kind on a modal chain of N masses (its set-up takes seconds: the
run's own engine, a continuation's family engine, a sweep point's, a locate grid value's, a
basin, diagram or Lyapunov point's), sends SIGINT to the process once the run sits in that set-up
(a fixed 0.5 s: the scene is checked in O(N) before), and asserts: vibro.Interrupted is raised
within LIMIT seconds of the signal; its result is None (interrupted before the run held anything)
or a Result with exit code 130: status 'interrupted', or a sweep's partial file with the points
it finished.
"""
import os
import signal
import threading
import time

import pytest
import vibro

N = 3000  # masses: the modes take seconds (O(N²) LAPACK), the check milliseconds
# 1 s: the guarantee (docs/results.md, "Signals"), as the CLI's; the wait for the GIL's next
# 50 ms look at the signals and a loaded 2-core machine (ctest -j2) make the rest.
LIMIT = 2.0


def chain(run):
    """A modal chain of N unit masses (proportional damping), driven at mass 0, one stop on it."""
    ones = ", ".join(["1"] * N)
    springs = ", ".join(["1"] * (N - 1))
    dampers = ", ".join(["0.02"] * (N - 1))
    cosine = ", ".join(["0.6"] + ["0"] * (N - 1))
    return (f"model: {{chain: {{masses: [{ones}], springs: [{springs}], dampers: [{dampers}], "
            f"left_wall: {{spring: 1, damper: 0.02}}}}}}\n"
            f"forcing: {{frequency: 0.8, cosine: [{cosine}]}}\n"
            "stops: [{mass: 0, side: upper, position: 0.1, restitution: 0.5}]\n"
            "solver: {engine: modal}\n" + run + "\n")


GRID = "path: forcing.frequency, linspace: [0.79, 0.81, 3]"
RUNS = {
    "simulate": "run: {periods: 1e6}",
    "sweep": "run: {kind: sweep, periods: 1e6, sweep: {parameters: [{" + GRID + "}]}}",
    "orbit": "run: {kind: orbit, transient_periods: 0, orbit: {period: 1}}",
    "continue": "run: {kind: continue, transient_periods: 0, continue: {path: forcing.frequency, range: [0.7, 0.9], "
                "step: 0.01}}",
    "locate": "run: {kind: locate, transient_periods: 0, locate: {" + GRID + "}}",
    "basin": "initial: {x: [%s], v: [%s]}\n" % (", ".join(["0"] * N), ", ".join(["0"] * N)) +
             "run: {kind: basin, basin: {parameters: [{path: 'initial.x[0]', linspace: [-0.1, 0.05, 2]}, "
             "{path: 'initial.v[0]', linspace: [-0.1, 0.1, 2]}]}}",
    "diagram": "run: {kind: diagram, transient_periods: 0, diagram: {" + GRID + ", transient: 1, points: 4, "
               "max_period: 2}}",
    "lyapunov": "run: {kind: lyapunov, transient_periods: 0, lyapunov: {" + GRID + ", transient: 1, align: 1, "
                "periods: 2}}",
}


@pytest.mark.parametrize("kind", list(RUNS))
def test_ctrl_c_in_a_bounded_set_up_raises_interrupted(kind):
    scene = vibro.Scene.from_text(chain(RUNS[kind]))
    assert scene.run_kind == kind and scene.engine == "modal"
    function = vibro.run_function(kind)
    sent = []

    def interrupt():
        sent.append(time.monotonic())
        os.kill(os.getpid(), signal.SIGINT)

    timer = threading.Timer(0.5, interrupt)
    timer.start()
    try:
        function(scene, threads=1)
        raise AssertionError("not interrupted")
    except vibro.Interrupted as stop:  # never a RuntimeError, nor a KeyboardInterrupt of Python's own
        ended = time.monotonic()
        result = stop.result
    finally:
        timer.cancel()  # never a SIGINT after the test, into whatever runs next
    assert sent, "the run ended before the signal"
    assert ended - sent[0] < LIMIT, f"{kind}: Interrupted {ended - sent[0]:.2f} s after SIGINT"
    if result is not None:
        assert result.exit_code == 130, kind
        if kind == "sweep":  # its partial file, as `vibro run` keeps OUT.partial: the points finished
            assert result.sweep.attrs["completed"] < result.sweep.attrs["points"]
        else:
            assert result.status == "interrupted", kind
