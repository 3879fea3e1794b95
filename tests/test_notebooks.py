"""The notebooks run (their code cells executed in order), in their small mode
(``JAXBELT_NOTEBOOK_SMALL=1``: coarse grids and short runs, set in each notebook's parameter
cell) and, marked slow, full-size (minutes each); each ``.ipynb`` holds the same code as its
jupytext ``.py`` pair."""

import json
from pathlib import Path

import pytest

NOTEBOOKS = sorted((Path(__file__).parent.parent / "notebooks").glob("*.ipynb"))


def code_cells(nb) -> list[str]:
    return ["".join(c["source"]) for c in nb["cells"] if c["cell_type"] == "code"]


def execute(path, capsys) -> dict:
    """Run the notebook's code cells in one namespace; check what the notebook promises."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    namespace = {}
    try:
        for src in code_cells(json.loads(path.read_text())):
            exec(compile(src, f"{path.name}", "exec"), namespace)
    finally:
        plt.close("all")
    if path.stem == "06_tolerance_design":
        assert "tolerated tilt" in capsys.readouterr().out
        # the optimiser's tilt puts the drift on the tolerance (the jitted drift of lateral_drift_mm)
        drift, _ = namespace["drift_and_grad"](namespace["alpha"])
        assert abs(float(drift) - 0.020) < 2e-4
    return namespace


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_executes(path, capsys, monkeypatch):
    monkeypatch.setenv("JAXBELT_NOTEBOOK_SMALL", "1")
    namespace = execute(path, capsys)
    assert namespace["SMALL"]
    if path.stem == "06_tolerance_design":
        assert namespace["N_ETA"] == 2


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_executes_full_size(path, capsys, monkeypatch):
    monkeypatch.delenv("JAXBELT_NOTEBOOK_SMALL", raising=False)
    assert not execute(path, capsys)["SMALL"]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_pair_in_sync(path):
    jupytext = pytest.importorskip("jupytext")
    pair = path.with_suffix(".py")
    assert pair.exists(), f"{path.name} has no jupytext pair {pair.name}"
    assert code_cells(jupytext.reads(pair.read_text(), fmt="py:percent")) == code_cells(json.loads(path.read_text())), \
        f"{path.name} and {pair.name} differ: run `jupytext --sync {pair}`"
