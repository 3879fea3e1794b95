"""One pass rule for every yield: the metric within the limit and, on a steered machine, the
actuator not saturated (:func:`jaxbelt.design.sampling.passes`), in the Monte Carlo as in the sweep."""

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
