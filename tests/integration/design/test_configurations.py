"""A study's question at many configurations (:mod:`jaxbelt.design.configurations`): the batch —
starts, one compiled steady solve per row, the read-out — gives what each configuration's own
solve or run gives."""

import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.design import make_study
from jaxbelt.design.configurations import at_configurations
from jaxbelt.design.metrics import limit_values_from_deviation
from jaxbelt.design.study import limit_values, with_limits

SCENE = "two-roller-steered"  # N = 180, PI loop on the idle roller about y
COMPONENTS = ["idle:ay", "drive:dx"]
THETAS = np.array([[0.05, 0.01], [-0.1, 0.0], [0.0, -0.02]])  # mrad, mm


@pytest.fixture(scope="module")
def machine():
    scene = jb.load_scene(SCENE)
    return jb.build_model(scene), jb.RunOptions.from_scene(scene)


@pytest.mark.parametrize("steady", [True, False])
def test_batch_equals_each_configuration_alone(machine, steady):
    model, opts = machine
    study = make_study(model, "lateral_max", opts, components=COMPONENTS, steady=steady,
                       t_eval=None if steady else 0.4)
    study = with_limits(study, (("lateral_max", 20.0), ("steering_max", 1.0)))
    batch = np.asarray(at_configurations(study, THETAS, limit_values_from_deviation))
    alone = np.array([np.asarray(limit_values(study, t)) for t in THETAS])
    assert batch.shape == (len(THETAS), 2) and np.all(np.isfinite(batch))
    np.testing.assert_allclose(batch, alone, rtol=1e-9, atol=1e-9)
    assert np.max(np.abs(batch[:, 0])) > 0.01  # the configurations move the belt


def test_no_configuration_gives_empty_outputs(machine):
    """An empty batch (e.g. a sweep chunk whose surrogate leaves nothing to run in full) gives
    outputs with no rows, and no solve."""
    from jaxbelt.design.configurations import evaluate_configs

    model, opts = machine
    study = make_study(model, "lateral_max", opts, components=COMPONENTS, steady=True)
    none = np.zeros((0, len(COMPONENTS)))
    limited = with_limits(study, (("lateral_max", 20.0), ("steering_max", 1.0)))
    assert np.asarray(at_configurations(limited, none, limit_values_from_deviation)).shape == (0, 2)
    out = evaluate_configs(study, none)
    assert out["metric"].shape == (0,) and out["lateral_um"].shape[0] == 0
