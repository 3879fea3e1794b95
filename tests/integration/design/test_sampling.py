"""Yield estimates (jaxbelt.design.sampling): Monte Carlo, Wilson, FORM, importance sampling, OpenTURNS."""

import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt import design
from jaxbelt.design import sampling


def test_monte_carlo_equals_a_brute_force_loop(study, metric_fn, dist, chunk):
    limit = 1.1 * float(design.metric_value(study, jnp.zeros(4)))
    mc = design.monte_carlo(study, dist, 12, limit, seed=5, chunk=chunk)  # two chunks, the last padded
    u = sampling.standard_normal_samples(12, 4, 5)
    loop = np.array([float(metric_fn(dist.transform(jnp.asarray(ui)))) for ui in u])
    np.testing.assert_allclose(mc.metric, loop, rtol=1e-10)  # batched vs one at a time: round-off
    assert mc.passed == int(np.sum(loop <= limit))
    lo, hi = mc.ci95
    assert lo <= mc.yield_ <= hi


def test_wilson_interval_matches_scipy():
    from scipy.stats import binomtest

    for k, n in ((0, 10), (7, 10), (990, 1000), (1000, 1000)):
        ci = binomtest(k, n).proportion_ci(method="wilson")
        np.testing.assert_allclose(design.wilson_interval(k, n), (ci.low, ci.high), atol=1e-12)


def test_distribution_file_validation(model2d):
    ok = {"roller": {"roller 2": {"rotation_mrad": {"dist": "normal", "sigma": [0.1, 0.1, 0.0]},
                                  "translation_mm": {"dist": "uniform", "half_width": [0.0, 0.0, 0.05]}}}}
    d = design.distribution_from_dict(ok, model2d)
    assert d.labels == ("roller 2:dz", "roller 2:ax", "roller 2:ay") and d.kind == ("uniform", "normal", "normal")
    bad = [
        ({"roller": {"roller 9": {}}}, "no roller"),
        ({"roller": {"roller 2": {"rotation_mrad": {"dist": "normal", "sigma": [-0.1, 0, 0]}}}}, "negative"),
        ({"roller": {"roller 2": {"rotation_mrad": {"dist": "normal", "sigma": [float("nan"), 0, 0]}}}}, "finite"),
        ({"roller": {"roller 2": {"rotation_mrad": {"dist": "gumbel", "sigma": [0.1, 0, 0]}}}}, "unknown distribution"),
        ({"roller": {"roller 2": {"rotation_mrad": {"dist": "normal", "sigma": [0, 0, 0.1]}}}}, "cannot vary"),
        ({"roller": {"roller 2": {"spin": {"dist": "normal", "sigma": [0, 0, 0.1]}}}}, "unknown key"),
        ({"roller": {"roller 2": {"rotation_mrad": {"dist": "normal", "sigma": [0, 0, 0]}}}}, "nothing varies"),
    ]
    for data, word in bad:
        with pytest.raises(ValueError, match=word):
            design.distribution_from_dict(data, model2d)


@pytest.fixture(scope="module")
def limit_13(study, dist, chunk):
    """A limit 1.3 times the nominal metric, and a 400-sample Monte Carlo against it (shared by
    the FORM / importance-sampling and the OpenTURNS comparisons)."""
    limit = 1.3 * float(design.metric_value(study, jnp.zeros(4)))
    return limit, design.monte_carlo(study, dist, 400, limit, seed=11, chunk=chunk)


def test_form_and_importance_sampling_agree_with_monte_carlo(study, limit_13, dist, chunk):
    limit, mc = limit_13
    f = design.form(study, dist, limit)
    assert f.converged and f.beta > 0
    assert np.isclose(float(design.metric_value(study, jnp.asarray(f.theta_star))), limit, rtol=1e-6)
    is_ = design.importance_sampling(study, dist, limit, f.u_star, n=400, chunk=chunk)
    assert is_.ci95[0] - 0.03 <= mc.yield_ <= is_.ci95[1] + 0.03


def test_monte_carlo_and_form_match_openturns(study, metric_fn, limit_13, dist):
    """The same limit state (metric > limit under the same input laws) through OpenTURNS' FORM
    (Abdo–Rackwitz) and its Monte Carlo."""
    ot = pytest.importorskip("openturns")
    limit, mc = limit_13
    df = lambda x: design.value_and_gradient(study, jnp.asarray(x))[1]  # noqa: E731  (reverse mode)
    fun = ot.PythonFunction(4, 1, lambda x: [float(metric_fn(jnp.asarray(x)))],
                            gradient=lambda x: [[float(v)] for v in df(x)])
    marginals = [ot.Normal(0.0, s) if k == "normal" else ot.Uniform(-s, s) for k, s in zip(dist.kind, dist.scale)]
    X = ot.RandomVector(ot.JointDistribution(marginals))
    event = ot.ThresholdEvent(ot.CompositeRandomVector(fun, X), ot.Greater(), limit)
    solver = ot.AbdoRackwitz()
    solver.setMaximumIterationNumber(100)
    ref = ot.FORM(solver, event, [0.0] * 4)
    ref.run()
    ours = design.form(study, dist, limit)
    assert np.isclose(ours.beta, ref.getResult().getHasoferReliabilityIndex(), rtol=1e-5)
    assert np.isclose(1 - ours.yield_, ref.getResult().getEventProbability(), rtol=1e-4)
    ot.RandomGenerator.SetSeed(7)
    mc_ref = ot.ProbabilitySimulationAlgorithm(event, ot.MonteCarloExperiment())
    mc_ref.setMaximumOuterSampling(400)
    mc_ref.setMaximumCoefficientOfVariation(0.0)
    mc_ref.run()
    p_ref = mc_ref.getResult().getProbabilityEstimate()
    p = 1 - mc.yield_
    sd = np.sqrt(p * (1 - p) / 400 + p_ref * (1 - p_ref) / 400)
    assert abs(p - p_ref) <= 3.5 * sd + 1e-12

