"""A yield sweep in steady operation: the steady state's linear response (its implicit derivatives)
stands in where its validated bound decides, steady solves elsewhere, and its calls agree with
steady solves of the same configurations."""

import jax
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.design import distribution_from_dict, evaluate_metric, make_study, run_sweep
from jaxbelt.steady import forward_jacobian, map_configurations

SCENE = "two-roller-steered"  # N = 180, PI loop on the idle roller about y
DIST = {"roller": {"idle": {"rotation_mrad": {"dist": "normal", "sigma": [0.02, 0.3, 0.0]}},
                   "drive": {"translation_mm": {"dist": "normal", "sigma": [0.01, 0.0, 0.0]}}}}


@pytest.fixture(scope="module")
def steady_study():
    scene = jb.load_scene(SCENE)
    model, opts = jb.build_model(scene), jb.RunOptions.from_scene(scene)
    dist = distribution_from_dict(DIST, model)
    study, linear = make_study(model, "lateral_max", opts, components=list(dist.labels), jacobian=True, steady=True)
    return study, dist, linear


def test_steady_sweep_linear_response_agrees_with_steady_solves(steady_study):
    study, dist, linear = steady_study
    # a limit inside the spread of the metric (33.7–36.1 µm: the drive's own skew gives 35), so that
    # both verdicts occur
    res = run_sweep(study, dist, 48, limit_um=35.3, seed=3, chunk=16, rom="auto", with_form=False, linear=linear)
    assert res.rom.used and res.rom.validation.training_runs == 0
    assert "linear response of steady operation" in res.rom.validation.description
    assert 0 < res.passed < res.samples
    assert res.reduced_runs + res.full_runs - res.rom.validation_runs == res.samples
    # the surrogate's calls against steady solves of the same configurations
    from jaxbelt.design.sampling import sample_configurations

    thetas = sample_configurations(dist, 48, 3)
    pick = np.arange(0, 48, 6)
    full = evaluate_metric(study, thetas[pick])
    np.testing.assert_array_equal(full <= 35.3, res.metric_values[pick] <= 35.3)
    assert np.max(np.abs(full - res.metric_values[pick])) <= res.rom.validation.max_bound_um


def test_sequential_batch_and_jacobian_equal_the_batched_ones(steady_study):
    """:func:`jaxbelt.steady.map_configurations` and :func:`jaxbelt.steady.forward_jacobian` give
    what ``vmap`` and ``jacfwd`` give (they only order the solves differently)."""
    study, _, _ = steady_study
    from jaxbelt.design.study import run_deviation

    thetas = np.array([[0.01, 0.2, 0.005], [-0.02, -0.3, 0.01]])[:, :study.space.size]
    one = jax.jit(lambda t: run_deviation(study, t)[1])
    seq = np.asarray(jax.jit(lambda x: map_configurations(one, x))(thetas))
    # equal to well within the solve's tolerance (1e-5 µm): a batch's Krylov loops round differently
    np.testing.assert_allclose(seq, np.asarray(jax.vmap(one)(thetas)), rtol=0, atol=1e-6)
    J = np.asarray(jax.jit(lambda t: forward_jacobian(one, t))(thetas[0]))
    # to the tangents' own accuracy (their GMRES stops at 1e-8 of the residual; the slow loop modes
    # amplify that to about 1e-5 of a column)
    np.testing.assert_allclose(J, np.asarray(jax.jit(jax.jacfwd(one))(thetas[0])), rtol=1e-4, atol=1e-6)


def test_a_steered_sweep_holds_the_limits_tolerance_holds(steady_study):
    """On a steered machine the sweep judges what ``tolerance`` holds — lateral and longitudinal
    deviation and the actuator angle — as one metric on the scale of the first limit: a sample
    passes exactly where each limit's own value is within it."""
    from jaxbelt.design import with_limits
    from jaxbelt.design.sampling import sample_configurations
    from jaxbelt.design.tolerance import _limit_values_batch

    study, dist, linear = steady_study
    names = (("lateral_max", 35.3), ("longitudinal_max", 35.3), ("steering_max", float(study.range_mrad)))
    limited = with_limits(study, names)
    res = run_sweep(limited, dist, 24, limit_um=35.3, seed=3, chunk=8, rom="auto", with_form=False, linear=linear)
    assert [x.metric for x in res.limits] == ["lateral_max", "longitudinal_max", "steering_max"]
    thetas = sample_configurations(dist, 24, 3)
    pick = np.arange(0, 24, 4)
    each = np.asarray(_limit_values_batch(limited, thetas[pick]))  # (m, 3), each in its own unit
    lims = np.array([v for _, v in names])
    np.testing.assert_array_equal(np.all(each <= lims, axis=1), res.metric_values[pick] <= 35.3)
    np.testing.assert_allclose(res.metric_values[pick], 35.3 * np.max(each / lims, axis=1),
                               atol=res.rom.validation.max_bound_um + 1e-9)
    with pytest.raises(ValueError, match="first limit"):
        run_sweep(limited, dist, 4, limit_um=20.0, rom="off", with_form=False)
