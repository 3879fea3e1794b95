"""The sampling pieces of the yield (jaxbelt.design.sampling): one pass rule for every yield (the
metric within the limit and, on a steered machine, the actuator not saturated: :func:`passes`), in
the Monte Carlo as in the sweep and importance sampling; the configurations a seed draws."""

from types import SimpleNamespace

import numpy as np

from jaxbelt.design import sampling


def test_passes_fails_a_saturated_actuator_and_a_nan_metric():
    metric = np.array([1.0, 19.9, 20.0, 25.0, np.nan])
    np.testing.assert_array_equal(sampling.passes(metric, 20.0), [True, True, True, False, False])
    sat = np.array([False, True, False, False, False])
    np.testing.assert_array_equal(sampling.passes(metric, 20.0, sat), [True, False, True, False, False])


def test_monte_carlo_counts_saturation_as_failure(monkeypatch):
    labels = ["roller 2:ay"]
    study = SimpleNamespace(space=SimpleNamespace(size=1, labels=lambda: labels))
    dist = SimpleNamespace(labels=labels, transform=lambda u: u)
    fake = {"metric": np.array([1.0, 2.0, 3.0, 30.0]), "saturated": np.array([False, True, False, False]),
            "steering_mrad": np.array([0.1, 3.0, 0.2, 0.3]), "longitudinal_um": np.zeros((4, 2))}
    monkeypatch.setattr(sampling, "evaluate_configs", lambda study, thetas, chunk, progress: fake)
    mc = sampling.monte_carlo(study, dist, 4, 20.0)
    assert mc.passed == 2 and mc.yield_ == 0.5  # the saturated one fails though its metric is small


def test_importance_sampling_counts_a_nan_metric_as_a_failure():
    """An unconverged evaluation (NaN) fails in importance sampling as in the Monte Carlo: with
    every sample NaN the failure probability is the mean weight, not zero."""
    labels = ("roller 2:ay",)
    study = SimpleNamespace(space=SimpleNamespace(size=1, labels=lambda: list(labels)))
    dist = sampling.Distribution(labels, ("normal",), (0.1,))
    r = sampling.importance_sampling(study, dist, 20.0, np.array([2.0]), n=50, seed=3,
                                     metric_of=lambda th: np.full(len(th), np.nan))
    u = 2.0 + np.random.default_rng(3).standard_normal((50, 1))
    w = np.exp(-u @ np.array([2.0]) + 2.0)
    assert r.failure_probability == np.mean(w) and r.yield_ == 1.0 - np.mean(w)


def test_a_distribution_samples_its_laws():
    """The configurations of a seed under normal and uniform laws: ``σ u`` and ``h (2Φ(u) − 1)`` of
    the seed's standard normal samples (the first n for every n), and each law's standard deviation
    (``h / √3`` for a uniform one)."""
    from scipy.stats import norm

    dist = sampling.Distribution(("a:dx", "a:ay"), ("normal", "uniform"), (0.02, 0.3))
    u = np.random.default_rng(7).standard_normal((40, 2))
    th = sampling.sample_configurations(dist, 40, 7)
    np.testing.assert_allclose(th[:, 0], 0.02 * u[:, 0], rtol=1e-14)
    np.testing.assert_allclose(th[:, 1], 0.3 * (2 * norm.cdf(u[:, 1]) - 1), rtol=1e-12)
    np.testing.assert_array_equal(sampling.sample_configurations(dist, 10, 7), th[:10])
    assert dist.uniform == (False, True)
    np.testing.assert_allclose(dist.sigma, (0.02, 0.3 / np.sqrt(3.0)), rtol=1e-15)
    assert np.all(np.abs(th[:, 1]) <= 0.3)


def test_yield_estimate_is_the_pass_count_and_its_wilson_interval():
    metric = np.array([1.0, 19.9, 20.0, 25.0, np.nan, 3.0])
    sat = np.array([False, True, False, False, False, False])
    passed, ci95 = sampling.yield_estimate(metric, 20.0, sat)
    assert passed == 3 and ci95 == sampling.wilson_interval(3, 6)
    lo, hi = ci95
    assert lo < 0.5 < hi


def test_few_failures_leave_the_tail_to_importance_sampling():
    assert sampling.few_failures(5, 100) and not sampling.few_failures(6, 100)
    assert sampling.few_failures(10, 10_000) and not sampling.few_failures(11, 10_000)  # 0.1 %


def test_yield_statistics_without_a_linear_response_is_the_monte_carlo_estimate():
    """No linear response: no FORM, no importance sampling, nothing evaluated (the study is not
    read)."""
    metric = np.array([1.0, 19.9, 20.0, 25.0, np.nan, 3.0])
    sat = np.array([False, True, False, False, False, False])
    stats = sampling.yield_statistics(None, None, 20.0, metric, sat)
    assert (stats.passed, stats.samples, stats.ci95) == (3, 6, sampling.yield_estimate(metric, 20.0, sat)[1])
    assert stats.form is None and stats.importance is None


def test_yield_statistics_runs_importance_sampling_only_for_a_yield_near_one(monkeypatch):
    """With the linear response, FORM runs; importance sampling follows where the samples saw few
    failures and the nominal configuration passes (β > 0), around FORM's design point, with the
    caller's sample count, seed, chunk and evaluation."""
    calls = []
    beta = [2.0]
    monkeypatch.setattr(sampling, "form", lambda study, dist, limit, response: SimpleNamespace(
        beta=beta[0], u_star=np.array([beta[0]])))
    monkeypatch.setattr(sampling, "importance_sampling", lambda *a, **k: calls.append((a, k)) or "IS")
    metric_of = object()
    few = np.r_[np.zeros(995), np.full(5, 30.0)]  # 5 failures in 1000
    stats = sampling.yield_statistics("study", "dist", 20.0, few, response=("r0", "J"), importance_samples=7,
                                      seed=3, chunk=2, metric_of=metric_of)
    assert stats.passed == 995 and stats.form.beta == 2.0 and stats.importance == "IS"
    (args, kwargs), = calls
    assert args[:3] == ("study", "dist", 20.0) and args[3][0] == 2.0
    assert kwargs == {"n": 7, "seed": 3, "chunk": 2, "metric_of": metric_of}
    many = np.r_[np.zeros(990), np.full(10, 30.0)]
    assert sampling.yield_statistics("study", "dist", 20.0, many, response=("r0", "J")).importance is None
    beta[0] = -1.0  # the nominal configuration fails: no design point to sample around
    assert sampling.yield_statistics("study", "dist", 20.0, few, response=("r0", "J")).importance is None
    assert len(calls) == 1
