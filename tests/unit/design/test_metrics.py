"""The metric table (jaxbelt.design.metrics.METRICS) as data: what each metric's other direction,
tracer quantities and soft maximum are, and the measure of several limits on one scale."""

import numpy as np
import pytest

from jaxbelt.design.metrics import METRICS, on_limit_scale


def test_the_other_direction_is_a_metric_of_the_same_kind_in_the_other_direction():
    for name, m in METRICS.items():
        if m.other_direction is None:
            continue
        other = METRICS[m.other_direction]
        assert other.unit == m.unit and other.aggregate == m.aggregate
        assert ("lateral" in name) != ("lateral" in other.name)
    assert METRICS["lateral_max"].other_direction == "longitudinal_max"
    assert METRICS["lateral_peak"].other_direction == "longitudinal_max"
    assert METRICS["walk_rate"].other_direction is None and METRICS["steering_max"].other_direction is None


@pytest.mark.parametrize("name,quantities", [("lateral_max", ("lateral",)), ("longitudinal_rms", ("longitudinal",)),
                                             ("lateral_peak", ("lateral",)), ("walk_rate", ("lateral",)),
                                             ("steering_max", ("longitudinal", "lateral"))])
def test_each_metric_names_the_deviations_it_reads(name, quantities):
    assert METRICS[name].quantities == quantities


def test_only_the_peak_over_a_window_is_smoothed():
    assert [n for n, m in METRICS.items() if m.soft_maximum] == ["lateral_peak"]


def test_several_limits_are_measured_on_the_first_ones_scale():
    values = np.array([[10.0, 1.5], [25.0, 0.3]])  # lateral µm, steering mrad
    limits = (("lateral_max", 20.0), ("steering_max", 3.0))
    np.testing.assert_allclose(on_limit_scale(values, limits), [20.0 * 0.5, 20.0 * 1.25])
    np.testing.assert_array_equal(on_limit_scale(values[:, 0], ()), values[:, 0])
