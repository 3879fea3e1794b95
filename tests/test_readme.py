"""The README's first Python example runs as pasted (it is the quick start a fresh install meets)."""

import re
from pathlib import Path

README = Path(__file__).resolve().parent.parent / "README.md"


def first_python_block(text: str) -> str:
    m = re.search(r"^```python\n(.*?)^```", text, re.S | re.M)
    assert m, "README.md has no ```python block"
    return m.group(1)


def test_readme_first_python_example_runs():
    code = first_python_block(README.read_text())
    assert "jb.simulate" in code  # the API quick start, not some other snippet
    namespace = {"__name__": "__readme__"}
    exec(compile(code, str(README), "exec"), namespace)
    traj = namespace["traj"]
    assert traj.tracer_u.shape[0] > 0 and bool((abs(traj.tracer_u) < 1.0).all())
