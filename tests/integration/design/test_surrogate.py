"""The reduced-model surrogate of a tolerance study (jaxbelt.design.surrogate): its bound holds on
fresh samples, for the response surface (the default) and the fully reduced POD step, and a sweep
with ``rom="auto"`` gives the full-model yield with reduced runs. Every vmapped full evaluation
here uses the sweep's default batch (64), so the module compiles one batched program."""

import json

import jax.numpy as jnp
import numpy as np
import pytest
from helpers import load, scene_with

import jaxbelt as jb
from jaxbelt import design
from jaxbelt.design import configurations, sampling
from jaxbelt.design.surrogate import ResponseSurface, fit_surrogate, training_configurations

LIMIT = 20.0  # µm


@pytest.fixture(scope="module")
def study():
    """Coarse, 30 steps (whole checkpoint chunks), the factorisation-reuse solver (cheaper to
    compile and to run; checked against the exact one in integrators/test_reuse.py)."""
    model, opts = load(scene_with(lambda d: d["mesh"].update(n_eta=3), "three-roller"))
    return design.make_study(model, "lateral_max", opts.replace(solver=jb.make_solver("direct", "reuse")), t_eval=0.6,
                             components="roller 2:rotation")


@pytest.fixture(scope="module")
def dist(study):
    return design.Distribution(tuple(study.space.labels()), ("normal", "uniform"), (0.1, 0.2))


@pytest.fixture(scope="module")
def surrogate(study, dist):
    return fit_surrogate(study, dist, LIMIT, seed=3)


@pytest.fixture(scope="module")
def pod_surrogate(study, dist):
    return fit_surrogate(study, dist, LIMIT, seed=3, method="pod")


def test_training_runs_are_nominal_and_plus_minus_the_spread(dist):
    th = training_configurations(dist)
    np.testing.assert_allclose(th, [[0, 0], [0.3, 0], [-0.3, 0], [0, 0.2], [0, -0.2]])


@pytest.mark.parametrize("which", ["surrogate", "pod_surrogate"])
def test_validation_record(which, request):
    sur = request.getfixturevalue(which)
    v = sur.validation
    assert v.method == {"surrogate": "response", "pod_surrogate": "pod"}[which]
    assert v.validation_runs == 5 + 12 and v.n_validation == 12
    if which == "pod_surrogate":
        assert v.n_modes >= 1 and v.singular_value_ratio >= v.sv_tol and v.steps_kept is None
    else:
        assert isinstance(sur.rom, ResponseSurface) and v.steps_kept == 1  # lateral_max: the last step
        assert "n_modes" not in v.to_dict()
    # calibrated: the bound is at least `safety` times the true error on every validation sample
    assert v.effectivity_min >= v.safety * (1 - 1e-9)
    assert v.max_true_error_um <= sur.bound_um == v.max_bound_um < 0.1 * LIMIT
    assert 0 < v.metric_range_um[0] < LIMIT < v.metric_range_um[1]  # the limit is in play
    json.dumps(v.to_dict())


@pytest.mark.parametrize("which", ["surrogate", "pod_surrogate"])
def test_metric_within_its_bound_of_the_full_metric_on_fresh_samples(study, dist, which, request):
    sur = request.getfixturevalue(which)
    u = sampling.standard_normal_samples(12, study.space.size, seed=101)
    thetas = np.asarray(dist.transform(jnp.asarray(u)))
    full = configurations.evaluate_configs(study, thetas, 64)
    pred = sur.evaluate(thetas)
    assert set(pred) == {"metric", "bound", "longitudinal_um", "lateral_um"}
    assert pred["lateral_um"].shape == full["lateral_um"].shape
    err = np.abs(pred["metric"] - full["metric"])
    assert np.all(err <= pred["bound"])
    assert np.max(np.abs(pred["lateral_um"] - full["lateral_um"])) < 1e-2 * LIMIT


def test_response_surface_reproduces_its_training_runs(study, dist, surrogate):
    train = training_configurations(dist)
    full = configurations.evaluate_configs(study, train, 64)
    pred = surrogate.predict(train)
    scale = np.max(np.abs(full["lateral_um"]))
    np.testing.assert_allclose(pred["lateral_um"], full["lateral_um"], rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(pred["metric"], full["metric"], rtol=1e-9, atol=1e-9 * scale)


def test_unknown_method_is_refused_before_any_run(study, dist):
    with pytest.raises(ValueError, match="method"):
        fit_surrogate(study, dist, LIMIT, method="krylov")
    with pytest.raises(ValueError, match="rom_method"):
        design.run_sweep(study, dist, 4, LIMIT, rom="auto", rom_method="krylov", with_form=False)


def test_bound_is_constant_inside_the_validated_range_and_grows_beyond(surrogate):
    direction = surrogate.widths / np.sqrt(len(surrogate.widths))  # rho = 1
    inside = surrogate.bound(np.array([0.5 * surrogate.rho_max * direction]))
    far = surrogate.bound(np.array([3 * surrogate.rho_max * direction]))
    assert np.isclose(inside[0], surrogate.bound_um) and np.isclose(far[0] - 1e-9, 9 * (surrogate.bound_um - 1e-9))


def test_non_finite_prediction_is_sent_to_a_full_run(surrogate, monkeypatch):
    good = surrogate.predict(np.zeros((2, 2)))
    bad = {k: v.copy() for k, v in good.items()}
    bad["metric"][1] = np.nan
    monkeypatch.setattr(surrogate, "predict", lambda thetas: {k: v.copy() for k, v in bad.items()})
    out = surrogate.evaluate(np.zeros((2, 2)))
    assert np.isfinite(out["bound"][0]) and out["bound"][1] == np.inf and out["metric"][1] == LIMIT


def test_sweep_with_rom_auto_matches_the_full_model_yield(study, dist):
    n = 64
    off = design.run_sweep(study, dist, n, LIMIT, seed=0, with_form=False)
    auto = design.run_sweep(study, dist, n, LIMIT, seed=0, rom="auto", with_form=False)
    assert off.reduced_runs == 0 and 0.1 < off.yield_ < 0.95
    assert auto.rom.used and auto.reduced_runs > 0
    assert auto.full_runs + auto.reduced_runs == n + auto.rom.validation_runs
    lo, hi = off.ci95
    assert lo <= auto.yield_ <= hi
    assert np.max(np.abs(auto.metric_values - off.metric_values)) < 0.1 * LIMIT
    # the errors (< 1e-4 µm) are far smaller than any sample's distance to the limit: same calls
    np.testing.assert_array_equal(auto.metric_values <= LIMIT, off.metric_values <= LIMIT)


def test_sweep_falls_back_to_full_runs_when_the_bound_is_too_large(study, dist, surrogate):
    limit = 2 * surrogate.bound_um  # the bound is half of this limit: not trusted
    res = design.run_sweep(study, dist, 12, limit, seed=0, rom="auto", with_form=False)
    assert not res.rom.used and res.reduced_runs == 0
    assert res.full_runs == 12 + res.rom.validation_runs  # training and validation count too
