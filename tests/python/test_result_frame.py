"""record.frame from Python: a base-excited scene's results in either frame, the frame named by
Scene.frame and Result.frame (/meta frame), and the two frames differing by the base motion
x_b(t) = a cos Ωt + b sin Ωt (ι = 1 on a chain) to one rounding."""
import numpy as np
import vibro

BASE = """name: shaken
model:
  chain:
    masses: [1]
    left_wall: {spring: 1, damper: 0.1}
forcing: {frequency: 0.8}
base:
  frame: relative
  displacement: {cosine: 0.05, sine: 0.02}
stops:
  - {mass: 0, side: upper, position: 0.1, restitution: 0.8, attached: base}
initial: {x: [0], v: [0]}
run: {transient_periods: 5, periods: 3}
"""


def test_results_in_either_frame_differ_by_the_base_motion():
    own = vibro.Scene.from_text(BASE + "record: {samples: {per_period: 16}}\n")
    other = vibro.Scene.from_text(BASE + "record: {samples: {per_period: 16}, frame: absolute}\n")
    assert own.frame == "relative" and other.frame == "absolute"
    a, b = vibro.simulate(own), vibro.simulate(other)
    assert a.frame == "relative" and b.frame == "absolute"
    t = a.samples.t
    assert np.array_equal(t, b.samples.t)
    w = 0.8
    xb = 0.05 * np.cos(w * t) + 0.02 * np.sin(w * t)
    vb = w * (-0.05 * np.sin(w * t) + 0.02 * np.cos(w * t))
    assert np.max(np.abs(b.samples.x[:, 0] - (a.samples.x[:, 0] + xb))) <= 4e-16
    assert np.max(np.abs(b.samples.v[:, 0] - (a.samples.v[:, 0] + vb))) <= 4e-16
    assert np.max(np.abs(xb)) > 0.01


def test_no_base_no_frame():
    scene = vibro.Scene.from_text(BASE.replace("base:\n  frame: relative\n  displacement: {cosine: 0.05, sine: 0.02}\n", "")
                                  .replace(", attached: base", ""))
    assert scene.frame is None and vibro.simulate(scene).frame is None
