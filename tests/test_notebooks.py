"""The notebooks run (their code cells executed in order), in their small mode
(``JAXBELT_NOTEBOOK_SMALL=1``: a narrower grid and a shorter run, set in a notebook's parameter
cell)."""

import json
from pathlib import Path

import pytest

NOTEBOOKS = sorted((Path(__file__).parent.parent / "notebooks").glob("*.ipynb"))


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_executes(path, capsys, monkeypatch):
    monkeypatch.setenv("JAXBELT_NOTEBOOK_SMALL", "1")
    nb = json.loads(path.read_text())
    namespace = {}
    for cell in nb["cells"]:
        if cell["cell_type"] == "code":
            exec(compile("".join(cell["source"]), f"{path.name}", "exec"), namespace)
    out = capsys.readouterr().out
    assert "tolerated tilt" in out
    assert namespace["SMALL"] and namespace["N_ETA"] == 2
    # the optimiser's tilt puts the drift on the tolerance (the jitted drift of lateral_drift_mm)
    drift, _ = namespace["drift_and_grad"](namespace["alpha"])
    assert abs(float(drift) - 0.020) < 2e-4
