"""docs/python.md: the quick start runs as written and reproduces the paper's fig. 4 panel at
Ω = 0.2561 (mass 1 sticks twice per period, mass 2 once: the README's fig. 4 (c)); every public
function and class of the module has a docstring, and help(vibro.simulate) says what it needs to."""
import inspect
import os
import pydoc
import re

import numpy as np
import vibro
from conftest import SOURCE


def test_quick_start_reproduces_fig4_at_0_2561(tmp_path, monkeypatch):
    text = (SOURCE / "docs/python.md").read_text()
    code = re.search(r"## Quick start.*?```python\n(.*?)```", text, re.S).group(1)
    assert len(code.strip().splitlines()) <= 20
    (tmp_path / "experiments").symlink_to(SOURCE / "experiments")
    monkeypatch.chdir(tmp_path)
    namespace = {}
    exec(compile(code, "docs/python.md", "exec"), namespace)
    assert (tmp_path / "fig4_omega_0.2561.png").stat().st_size > 10000
    r, scene = namespace["r"], namespace["scene"]
    assert scene.frequency == 0.2561 and r.status == "completed"
    per_period = np.bincount(r.contacts.stop) / scene.periods
    assert list(per_period) == [2.0, 1.0]
    assert np.allclose(r.poincare.x[1:], r.poincare.x[0], rtol=0, atol=1e-10)  # a period-1 orbit


def test_every_public_name_has_a_docstring():
    assert vibro.__doc__ and "docs/python.md" in vibro.__doc__
    for name in vibro.__all__:
        thing = getattr(vibro, name)
        if name != "__version__":
            assert inspect.getdoc(thing), name
        if inspect.isclass(thing) and thing.__module__ == "vibro":
            for member, value in vars(thing).items():
                if not member.startswith("_") and (callable(value) or isinstance(value, (property, classmethod))):
                    assert inspect.getdoc(getattr(thing, member)), f"{name}.{member}"


def test_help_of_simulate_is_useful():
    text = pydoc.render_doc(vibro.simulate, renderer=pydoc.plaintext)
    for needed in ("periods", "events, contacts, statistics, poincare", "samples", "Ctrl-C", "Interrupted",
                   "SceneError", "GIL"):
        assert needed in text, needed
    assert os.environ.get("PYTHONPATH") is None or vibro.__file__
