"""The speed/accuracy trade on the default scene (tracer error against wall time and memory);
see :mod:`jaxbelt.bench.pareto` for what is measured and against which truth.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/pareto.py [--quick]`` (or ``jaxbelt bench --only pareto``).
Writes ``results/pareto[_quick].json``, ``.png`` and ``.md`` (the Pareto front; the grid for an accuracy is
``--accuracy-um``'s to choose: ``accuracy_trade.py``).
"""

import sys

from _common import RESULTS
from jaxbelt.bench import pareto

if __name__ == "__main__":
    pareto.run(RESULTS, quick="--quick" in sys.argv)
