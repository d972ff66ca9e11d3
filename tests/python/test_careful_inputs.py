"""The module is as careful as the command: complex matrices and 2-D grids are refused, not
converted; Result.save never replaces what is not a regular file; an interpreter that exits while
a daemon thread is inside the engine stops the run and exits cleanly (it aborted, exit 134)."""
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import vibro
from conftest import PAPER, SOURCE

E = np.array([[2.0, -1.0], [-1.0, 1.0]])
STOPS = [{"mass": 0, "side": "lower", "position": -0.3, "restitution": 0.7}]


def matrices(**changes):
    arguments = dict(M=np.eye(2), C=0.1 * E, K=E, frequency=0.255, cosine=[0.5, 0.0], stops=STOPS)
    arguments.update(changes)
    return vibro.Scene.from_matrices(**arguments)


@pytest.mark.parametrize("changes", [dict(M=np.eye(2) + 0j), dict(K=E + 1e-3j), dict(cosine=[0.5 + 1j, 0.0]),
                                     dict(C=[[0.2, -0.1j], [0.1j, 0.1]])])
def test_complex_arrays_are_refused(changes):
    with pytest.raises(ValueError, match="expected real numbers"):
        matrices(**changes)


def test_a_grid_must_be_one_dimensional():
    scene = vibro.Scene.from_text(PAPER)
    with pytest.raises(ValueError, match=r"forcing.frequency: expected a 1-D sequence of values, got an array of shape \(2, 2\)"):
        vibro.sweep(scene, {"forcing.frequency": np.array([[0.25, 0.26], [0.27, 0.28]])}, periods=1)
    with pytest.raises(ValueError, match="sample_times: expected a 1-D sequence"):
        vibro.simulate(scene, periods=1, sample_times=[[0.1, 0.2]])
    with pytest.raises(ValueError, match="expected real numbers"):
        vibro.sweep(scene, {"forcing.frequency": [0.25 + 1j, 0.26]}, periods=1)


def test_save_replaces_only_a_regular_file(tmp_path):
    result = vibro.simulate(vibro.Scene.from_text(PAPER), periods=1, samples=0)
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(vibro.ResultError, match="exists and is not a regular file: not replaced"):
        result.save(fifo, overwrite=True)
    assert fifo.is_fifo() and sorted(p.name for p in tmp_path.iterdir()) == ["fifo"]
    (tmp_path / "folder").mkdir()
    with pytest.raises(vibro.ResultError, match="not a regular file"):
        result.save(tmp_path / "folder", overwrite=True)
    result.save(tmp_path / "r.h5")
    result.save(tmp_path / "r.h5", overwrite=True)  # a regular file is replaced
    assert vibro.read(tmp_path / "r.h5").meta["impacts"] == result.meta["impacts"]


@pytest.mark.parametrize("call", [
    "vibro.simulate(scene, periods=1e7, samples=0)",
    "vibro.sweep(scene, {'forcing.frequency': np.linspace(0.25, 0.26, 400)}, threads=2, samples=0)",
])
def test_exit_with_a_daemon_thread_inside_the_engine(call):
    script = textwrap.dedent(f"""
        import threading, time
        import numpy as np
        import vibro
        scene = vibro.Scene.load({str(SOURCE / 'experiments/wagg2004/fig2_sticking_orbit.yaml')!r})
        threading.Thread(target=lambda: {call}, daemon=True).start()
        time.sleep(0.5)  # the interpreter exits while the thread runs the engine
        """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, (done.returncode, done.stderr)
    assert "terminate" not in done.stderr and "Abort" not in done.stderr
