"""``jaxbelt bench``: the measured speed/accuracy trade and the baselines, in one entry point.

* :mod:`jaxbelt.bench.pareto` — tracer error against wall time and memory for grids, Δt, solvers,
  integrators, float32 and the reduced models on the default scene (``pareto.json/.png/.md``);
* :mod:`jaxbelt.bench.baselines` — jaxbelt against SciPy SuperLU (factor every step and factor
  once), the whole run, compilation, ``vmap`` batches, the source's reported speedups
  (``baselines.json/.png``), with :mod:`jaxbelt.bench.scipy_reference`, the same step in numpy +
  SciPy (SciPy is imported only when the baselines run);
* :mod:`jaxbelt.bench.timing` — the timing and output helpers, shared with ``benchmarks/``.

Timings are wall-clock on whatever machine runs them (recorded in each file); set
``OPENBLAS_NUM_THREADS=1`` on a shared machine. They are never asserted in tests.
"""

from __future__ import annotations

from pathlib import Path


def run_all(out_dir: Path, quick: bool = False, parts=("baselines", "pareto")) -> dict:
    """Every part into ``out_dir``; returns ``{part: payload}``."""
    from . import baselines, pareto  # here: the parts import the reduced models and tolerance design

    out = {}
    if "baselines" in parts:
        out["baselines"] = baselines.run(out_dir, quick=quick)
    if "pareto" in parts:
        out["pareto"] = pareto.run(out_dir, quick=quick)
    return out
