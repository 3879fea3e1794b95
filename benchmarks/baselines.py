"""jaxbelt against SciPy SuperLU (factor every step, factor once), the whole run, compilation,
``vmap`` batches and the source's reported speedups, side by side in one run; see
:mod:`jaxbelt.bench.baselines`.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/baselines.py [--quick]`` (or ``jaxbelt bench --only baselines``).
Writes ``results/baselines[_quick].json`` and ``.png``.
"""

import sys

from _common import RESULTS
from jaxbelt.bench import baselines

if __name__ == "__main__":
    baselines.run(RESULTS, quick="--quick" in sys.argv)
