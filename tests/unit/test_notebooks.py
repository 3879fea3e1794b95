"""The notebooks: each ``.ipynb`` holds the same code as its jupytext ``.py`` pair, and their use
of the jaxbelt API resolves (``notebook_api.check_notebook_api``: imports, attribute chains, call
keywords and required arguments, CLI options; no cell run) — both in the default run. Their execution is slow: in the
small mode (``JAXBELT_NOTEBOOK_SMALL=1``: coarse grids and short runs, set in each notebook's
parameter cell) 9–22 s a notebook, 75 s for the six — a third of the default suite's time, nearly
all of it compiling programs that the library's own tests compile on their scenes too; full-size,
minutes each. ``python -m pytest --runslow tests/unit/test_notebooks.py`` runs all of it,
``-m slow -k "executes and not full_size"`` the small runs alone."""

import json

import pytest
from helpers import REPO

NOTEBOOKS = sorted((REPO / "notebooks").glob("*.ipynb"))


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


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_api_resolves(path):
    """Every jaxbelt import, attribute, call keyword and CLI option the notebook uses exists."""
    from notebook_api import check_notebook_api

    source = "\n".join(code_cells(json.loads(path.read_text())))
    assert check_notebook_api(source, path.name) > 10


@pytest.mark.parametrize("snippet,word", [
    ("import jaxbelt as jb\njb.no_such_function()", "no attribute 'no_such_function'"),
    ("from jaxbelt import design\ndesign.sampling.no_such_sampler", "no attribute 'no_such_sampler'"),
    ("from jaxbelt.rom.error_estimate import no_such_name", "has no 'no_such_name'"),
    ("import jaxbelt as jb\njb.simulate(m, n_step=10, dt=0.01)", "takes no keyword 'n_step'"),
    ("import jaxbelt as jb\njb.simulate(m, n_steps=10)", "missing its required argument 'dt'"),
    ("import jaxbelt as jb\njb.load_scene('a', 'b', 'c', 'd', 'e', 'f')", "positional arguments"),
    ("from jaxbelt.cli import main as cli\ncli(['reduce', 'x', '--methd', 'dmd'])", "no option '--methd'"),
    ("from jaxbelt.cli import main as cli\ncli(['nosuchcommand'])", "no command"),
])
def test_notebook_api_check_catches_drift(snippet, word):
    """The static check fails on a renamed function, a missing submodule name, a wrong keyword,
    a missing required argument, too many positional arguments and an unknown CLI option or
    command (and passes their fixes, and a call whose arguments come from ``**options``)."""
    from notebook_api import check_notebook_api

    with pytest.raises(AssertionError, match=word):
        check_notebook_api(snippet)
    check_notebook_api("import jaxbelt as jb\nfrom jaxbelt.cli import main as cli\n"
                       "jb.simulate(m, n_steps=10, dt=0.01)\njb.simulate(m, **opts)\n"
                       "cli(['reduce', 'x', '--method', 'dmd'])")
