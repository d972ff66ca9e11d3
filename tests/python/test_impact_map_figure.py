"""tools/figures/impact_map.py draws a simulation's and a sweep's impact map, and refuses a file
without one (each in its own temporary directory)."""
import subprocess

import vibro
from conftest import SOURCE
from test_impact_map import SCENE

SCRIPT = SOURCE / "tools/figures/impact_map.py"


def draw(path, outdir):
    return subprocess.run(["/usr/bin/python3", str(SCRIPT), str(path), str(outdir)], capture_output=True, text=True,
                          timeout=120)


def test_simulation_and_sweep_maps_are_drawn(tmp_path):
    vibro.simulate(SCENE, output=tmp_path / "sim.h5")
    done = draw(tmp_path / "sim.h5", tmp_path / "sim")
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "sim/impact_map.png").stat().st_size > 0 and (tmp_path / "sim/impact_map.pdf").exists()
    vibro.sweep(SCENE, {"forcing.frequency": [0.25, 0.255, 0.26]}, output=tmp_path / "sweep.h5", threads=2)
    done = draw(tmp_path / "sweep.h5", tmp_path / "sweep")
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "sweep/impact_map.png").stat().st_size > 0


def test_a_file_without_a_map_is_refused(tmp_path):
    vibro.simulate(SCENE.replace("impact_map: true", "impact_map: false"), output=tmp_path / "plain.h5")
    done = draw(tmp_path / "plain.h5", tmp_path / "out")
    assert done.returncode == 1 and "no /impact_map" in done.stderr
