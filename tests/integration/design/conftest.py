"""Fixtures of the design tests: one coarse study shared by the modules that run it.

``study``: 12 steps, a whole number of the scan's checkpoint chunks, so each compiled run holds
one copy of the step; the factorisation-reuse solver, 4× faster here, whose runs
``tests/integration/integrators/test_reuse.py`` checks against the exact one and whose
derivatives the Jacobian tests of ``test_sensitivity.py`` check against full runs
(``tests/integration/test_grad.py``'s slow cases check its gradients against central
differences). The modules that use it reuse its compiled programs: the value and gradient, the
forward Jacobian, the vmapped batches of ``chunk`` configurations, the jitted metric. The fixtures
are session-scoped: several modules of this folder share them, and the suite's ordering
(heaviest module first, tests/conftest.py) interleaves this folder's modules with others', which
would tear a package-scoped fixture down and build it again.
"""

import jax
import pytest
from helpers import coarse

import jaxbelt as jb
from jaxbelt import design
from jaxbelt.design import sampling


@pytest.fixture(scope="session")
def loaded2d():
    # misaligned base: the metric is smooth at theta = 0; two grid lines across (the belt edges,
    # N = 434): the studies run ~2000 configurations
    return coarse("three-roller-t72", n_eta=2)


@pytest.fixture(scope="session")
def model2d(loaded2d):
    return loaded2d[0]


@pytest.fixture(scope="session")
def study(loaded2d):
    model2d, opts = loaded2d
    return design.make_study(model2d, "lateral_rms", opts.replace(solver=jb.make_solver("direct", "reuse")), t_eval=0.24,
                             components="roller 2:rotation,roller 3:dx,roller 3:dz")


@pytest.fixture(scope="session")
def chunk():
    """Every batched evaluation of the study: one compiled vmap of 8 configurations."""
    return 8


@pytest.fixture(scope="session")
def metric_fn(study):
    """The study's metric, jit-compiled once."""
    return jax.jit(lambda t: design.metric_value(study, t))


@pytest.fixture(scope="session")
def dist(study):
    """The input laws of the study's four components: normal and uniform, alternating."""
    kinds, scales = ("normal", "uniform", "normal", "uniform"), (0.2, 0.3, 0.05, 0.05)
    return sampling.Distribution(tuple(study.space.labels()), kinds[: study.space.size], scales[: study.space.size])
