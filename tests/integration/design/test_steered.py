"""Tolerance design on a steered machine: the closed-loop metrics over the evaluation window,
their linearity below saturation, the tolerance box with several limits verified by full
closed-loop runs, saturation counted as a failure by the sweep, the response-surface surrogate
standing in with the loop closed, and the design commands' default scene.

One coarse copy of ``three-roller-steered`` (3 grid lines across, 5 elements per arc: N = 252;
100 steps = 2 s, a whole number of the scan's checkpoint chunks; window the last 20 steps) and
one study on two components; the tests reuse its compiled programs (the vmapped batch of 8, the
forward Jacobian, the batch of limit values). The narrow-range copy differs only in the
actuator's range (an array leaf), so it runs the same programs."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import load, scene_with

from jaxbelt import design
from jaxbelt.cli import build_parser
from jaxbelt.design.surrogate import fit_surrogate
from jaxbelt.design.sweep import ROM_STEERED

COMPONENTS = "roller 1:ax,roller 3:dz"
CHUNK = 8


def _coarse(d):
    d["mesh"] = {"n_eta": 3, "roller_elements": [5, 5, 5], "free_elements": [10, 7, 7]}
    d["time"] = {"dt_s": 0.02, "t_end_s": 2.0}


@pytest.fixture(scope="module")
def study_and_linear():
    from jaxbelt import make_solver

    model, opts = load(scene_with(_coarse, "three-roller-steered"))
    # with its Jacobian, as jaxbelt tolerance builds it: the reference is the forward-mode run's primal
    return design.make_study(model, "lateral_max", opts.replace(solver=make_solver("direct", "reuse")),
                             components=COMPONENTS, jacobian=True)


@pytest.fixture(scope="module")
def study(study_and_linear):
    return study_and_linear[0]


@pytest.fixture(scope="module")
def linear(study_and_linear):
    return study_and_linear[1]


def _batch(rows):
    th = np.zeros((CHUNK, 2))
    th[:len(rows)] = rows
    return th


def test_window_and_reference(study):
    assert study.steered and study.window == 20 and study.t_window == pytest.approx((1.6, 2.0))
    assert study.range_mrad == pytest.approx(3.0)
    out = design.evaluate_configs(study, _batch([[0.0, 0.0]]), CHUNK)
    # the aligned steered machine against itself: noise and edge profile cancel
    assert abs(out["metric"][0]) < 1e-6 and not out["saturated"][0]
    assert 0 < out["steering_mrad"][0] < 0.1  # the loop answers the sensor noise and the edge profile


def test_closed_loop_metrics_are_linear_below_saturation(study):
    rows = [[0.0, 0.0], [0.05, 0.0], [0.1, 0.0], [0.0, 0.02], [0.0, 0.04]]
    out = design.evaluate_configs(study, _batch(rows), CHUNK)
    m, lat = out["metric"], out["lateral_um"]
    assert m[1] > 1.0 and m[3] > 1.0 and not np.any(out["saturated"][:5])
    assert m[2] == pytest.approx(2 * m[1], rel=1e-3) and m[4] == pytest.approx(2 * m[3], rel=1e-3)
    np.testing.assert_allclose(lat[2], 2 * lat[1], atol=1e-3 * np.abs(lat[2]).max())
    # the steering angle is affine: its change from the aligned run doubles too
    s = out["steering_mrad"]
    assert s[2] - s[0] == pytest.approx(2 * (s[1] - s[0]), rel=0.05)


def test_box_with_several_limits_verified_by_closed_loop_runs(study, linear):
    box = design.tolerance_box(study, 20.0, limits={"longitudinal_max": 20.0, "steering_max": 3.0}, linear=linear)
    assert box.verified and 0.97 * 20 <= box.worst_case_um <= 20
    assert [x.metric for x in box.limits] == ["lateral_max", "longitudinal_max", "steering_max"]
    assert box.binding_limit == "lateral_max" and [x.binds for x in box.limits] == [True, False, False]
    for row in box.verification:  # every full closed-loop run within every limit
        assert row.full_by_limit["lateral_max"] <= 20.0 and row.full_by_limit["steering_max"] <= 3.0
    lat = box.limits[0]
    assert lat.worst_case == pytest.approx(lat.predicted_worst, rel=0.01)  # linear in closed loop
    # a tight steering range binds instead, and the box shrinks
    tight = design.tolerance_box(study, 20.0, limits={"longitudinal_max": 20.0, "steering_max": 0.02}, linear=linear)
    assert tight.verified and tight.binding_limit == "steering_max"
    assert tight.limits[2].worst_case <= 0.02 and tight.limits[0].worst_case < 20.0
    assert np.all(tight.half_widths <= box.half_widths * (1 + 1e-9))
    assert tight.to_dict()["binding_limit"] == "steering_max"
    # the error bars against the box's own grid: its verification values and the aligned
    # reference (the loop's steering angle in the floor) meet a re-run, no change but round-off
    from jaxbelt.design.tolerance import box_discretisation

    same = box_discretisation(tight, study, study.model, study.options)
    assert same.floor_um > 0 and same.floor_fine_um == pytest.approx(same.floor_um, rel=1e-9)
    assert same.worst_case_fine_um == pytest.approx(same.worst_case_um, rel=1e-9)
    # the worst corners (those within NEAR_WORST of the worst) and the aligned reference
    assert abs(same.half_width_relative_change) < 1e-8 and 2 <= same.runs <= len(tight.corners) + 1


def test_sweep_counts_saturation_as_failure(study):
    narrow = eqx.tree_at(lambda m: m.control.limit, study.model, jnp.asarray([0.05e-3]))
    st = design.make_study(narrow, "lateral_max", study.options, components=COMPONENTS)
    dist = design.Distribution(("roller 1:ax", "roller 3:dz"), ("normal", "normal"), (0.08, 0.001))
    res = design.run_sweep(st, dist, CHUNK, limit_um=1e4, chunk=CHUNK, with_form=False, rom="auto")
    mc = design.monte_carlo(st, dist, CHUNK, 1e4, chunk=CHUNK)
    sat = np.asarray(mc.outputs.saturated)
    assert 0 < sat.sum() < CHUNK and np.all(mc.metric <= 1e4)  # only saturation fails here
    assert res.saturated == int(sat.sum()) and res.passed == CHUNK - res.saturated
    assert res.range_mrad == pytest.approx(0.05) and res.steering_max_mrad >= 0.999 * 0.05
    # the response surface stands in with the loop closed, but never decides a saturation: every
    # configuration it predicts near the range is re-run in full
    assert res.rom.used and res.rom.validation.steering_bound_mrad > 0
    # the saturated ones are exactly those whose actuator reached its range
    assert np.array_equal(sat, np.asarray(mc.outputs.steering_mrad) >= 0.999 * 0.05)
    pod = design.run_sweep(st, dist, CHUNK, limit_um=1e4, chunk=CHUNK, with_form=False, rom="auto", rom_method="pod")
    assert pod.rom == design.ReducedModelUse(used=False, reason=ROM_STEERED) and pod.full_runs == CHUNK
    assert pod.to_dict()["rom"] == {"used": False, "reason": ROM_STEERED}
    assert pod.saturated == res.saturated
    # the yield's error bar against the sweep's own grid: the samples and the aligned reference in
    # one batch meet the sweep's runs, no verdict changes
    from jaxbelt.design.sweep import yield_discretisation

    same = yield_discretisation(res, st, st.model, st.options)
    # no sample lies within 10 % of the 1e4 µm limit: the two nearest measure the metric's change
    assert same.samples == 2 and same.flipped == 0 and same.bias == 0.0
    assert same.metric_relative_change < 1e-9


def test_aligned_values_read_the_reference_without_a_run(study):
    """What the metrics read on the aligned run, from the study's reference alone, equals a full
    run at θ = 0 of the aligned scene: zero deviation, the loop's own steering angle (nonzero:
    sensor noise and the wavy edge keep it working), and each limit's value with several
    limits (the programs of the sweep above)."""
    from jaxbelt.design.metrics import aligned_values

    run = design.evaluate_configs(study, np.zeros((CHUNK, 2)), chunk=CHUNK)
    metric, none = aligned_values(study)
    assert none is None and float(metric) == 0.0  # the batched run at θ = 0 equals it to round-off
    assert float(run["metric"][0]) == pytest.approx(0.0, abs=1e-9)
    steer = float(run["steering_mrad"][0])
    assert steer > 1e-3
    _, values = aligned_values(design.with_limits(study, {"lateral_max": 20.0, "steering_max": 3.0}))
    assert np.asarray(values) == pytest.approx([0.0, steer], rel=1e-9, abs=1e-9)


def test_study_with_its_jacobian_predicts_full_runs(study, linear):
    """The study built with its Jacobian (one forward-mode run: the reference is its primal, and
    the closed-loop runs at θ = 0 meet it, test above): the linear response read from its
    derivatives, ``max |J θ|``, is the metric the full closed-loop runs give at small
    misalignments (the batch of the sweep above)."""
    assert isinstance(linear, design.LinearDeviation)
    r0, J = design.response_jacobian(study, linear=linear)
    assert np.all(r0 == 0.0) and J.shape[1] == 2
    h = 0.002  # mm / mrad: well inside the linear range (the slow test below: 1e-6 relative at 0.05)
    thetas = np.array([[h, 0.0], [-h, 0.0], [0.0, h], [0.0, -h], [h, -h]])
    full = design.evaluate_configs(study, _batch(thetas), chunk=CHUNK)["metric"][:len(thetas)]
    predicted = np.max(np.abs(thetas @ J.T), axis=1)
    assert np.min(predicted) > 1e-3
    np.testing.assert_allclose(full, predicted, rtol=1e-3)


def test_study_with_its_jacobian_equals_a_study_and_then_its_jacobian(study, linear):
    """``make_study(..., jacobian=True)`` on the aligned machine: one forward-mode run gives the
    reference (its primal) and the derivatives; the linear response read from them, with several
    limits, equals the Jacobian of full runs taken after the study (two programs)."""
    import jax

    from jaxbelt import make_solver
    from jaxbelt.design.metrics import aligned_values

    lin = study
    study = design.make_study(lin.model, "lateral_max", lin.options.replace(solver=make_solver("direct", "reuse")),
                              components=COMPONENTS)
    assert jax.tree.structure(study) == jax.tree.structure(lin)  # the same study: the same programs run it
    np.testing.assert_allclose(lin.ref_u, study.ref_u, rtol=0, atol=1e-15)
    np.testing.assert_allclose(lin.ref_angle, study.ref_angle, rtol=0, atol=1e-12)
    limits = {"longitudinal_max": 20.0, "steering_max": 3.0}
    for a, b in ((study, lin), (design.with_limits(study, limits), design.with_limits(lin, limits))):
        r0, J = design.response_jacobian(a)
        r0_lin, J_lin = design.response_jacobian(b, linear=linear)  # no run: read from the linear deviations
        assert np.abs(J).max() > 0.1  # µm per mm or mrad; with limits, per limit
        np.testing.assert_allclose(r0_lin, r0, rtol=0, atol=1e-9 * np.abs(r0).max() + 1e-12)
        np.testing.assert_allclose(J_lin, J, rtol=0, atol=1e-9 * np.abs(J).max())
    # the linear deviations at θ = 0 read what the reference reads
    assert np.asarray(aligned_values(design.with_limits(lin, limits))[1]) == pytest.approx(
        np.asarray(aligned_values(design.with_limits(study, limits))[1]), rel=1e-12)
    # away from θ = 0 the study runs as before
    theta = np.array([0.01, -0.005])
    assert design.response_jacobian(lin, theta)[0] == pytest.approx(design.response_jacobian(study, theta)[0],
                                                                     rel=1e-9, abs=1e-12)


def test_response_surface_stands_in_with_the_loop_closed(study):
    """``--rom auto`` on the steered machine: the surrogate, trained and validated by closed-loop
    runs, predicts the metric and the actuator angle of fresh configurations as the full runs do."""
    dist = design.Distribution(("roller 1:ax", "roller 3:dz"), ("normal", "normal"), (0.03, 0.01))
    sur = fit_surrogate(study, dist, limit_um=20.0, n_validation=4)
    thetas = np.array([[0.02, -0.01], [-0.05, 0.015], [0.01, 0.02], [0.0, -0.02]])
    pred = sur.evaluate(thetas)
    full = design.evaluate_configs(study, _batch(thetas), CHUNK)
    np.testing.assert_allclose(pred["metric"], full["metric"][:4], atol=max(1e-3, sur.error_um))
    np.testing.assert_allclose(pred["steering_mrad"], full["steering_mrad"][:4],
                               atol=max(1e-6, sur.steering_error_mrad))
    assert np.all(pred["steering_bound"] > 0) and not np.any(pred["saturated"])


def test_design_commands_default_to_the_steered_machine():
    parser = build_parser()
    for argv in (["tolerance"], ["sensitivity"], ["sweep", "--dist", "d.toml"]):
        assert parser.parse_args(argv).scene == "three-roller-steered"
    args = parser.parse_args(["tolerance"])
    assert args.limit_um == 20.0 and args.steering_limit_mrad is None
