"""Tolerance design: parameters, metrics, gradients (= central differences), the tolerance box
(analytic on a linear model, verified by full runs), Monte Carlo (= a brute-force loop), FORM,
importance sampling, the sweep store.

Most tests share one coarse study (``study``: 12 steps, a whole number of the scan's checkpoint
chunks, so each compiled run holds one copy of the step; the factorisation-reuse solver, 4×
faster here, whose runs test_reuse.py checks against the exact one and whose derivatives the
Jacobian tests below check against full runs; test_grad.py's slow cases check its gradients
against central differences) and reuse its compiled programs: the value and gradient, the
forward Jacobian, the vmapped batches of 8 configurations, the jitted metric. The 1D gradient
check runs the scene's exact solver."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import load, scene_with

import jaxbelt as jb
from jaxbelt import design
from jaxbelt.design import linear_box, sampling
from jaxbelt.infra.store import load_sweep


def coarse(name, n_eta=3):
    """``(model, options)`` of a built-in scene on a coarser grid."""
    return load(scene_with(lambda d: d.setdefault("mesh", {}).update(n_eta=n_eta), name))


@pytest.fixture(scope="module")
def loaded2d():
    # misaligned base: the metric is smooth at theta = 0; two grid lines across (the belt edges,
    # N = 434): the studies below run ~2000 configurations
    return coarse("three-roller-t72", n_eta=2)


@pytest.fixture(scope="module")
def model2d(loaded2d):
    return loaded2d[0]


@pytest.fixture(scope="module")
def study(loaded2d):
    model2d, opts = loaded2d
    return design.make_study(model2d, "lateral_rms", opts.replace(solver=jb.make_solver("direct", "reuse")), t_eval=0.24,
                             components="roller 2:rotation,roller 3:dx,roller 3:dz")


CHUNK = 8  # every batched evaluation of the study: one compiled vmap of 8 configurations


@pytest.fixture(scope="module")
def metric_fn(study):
    """The study's metric, jit-compiled once for the module."""
    return jax.jit(lambda t: design.metric_value(study, t))


# ----------------------------------------------------------------------------- parameters


@pytest.mark.slow
def test_parameter_space_excludes_structural_zeros(model2d):
    sp = design.parameter_space(model2d)
    assert sp.size == 15 and all(not lab.endswith(":az") for lab in sp.labels())
    assert design.parameter_space(model2d, "roller 2:rotation").labels() == ["roller 2:ax", "roller 2:ay"]
    for bad, word in (("roller 9", "no roller"), ("roller 2:bogus", "unknown component"),
                      ("roller 2:az", "no static effect"), ("", "names no component")):
        with pytest.raises(ValueError, match=word):
            design.parameter_space(model2d, bad)
    tension = jb.load_model("two-roller-1d-tension")
    sp1 = design.parameter_space(tension)
    assert all(lab.endswith(":dx") for lab in sp1.labels())
    assert any("force/torque-loaded" in why for _, why in sp1.structural)
    # 2D: the tension roller's x is set by its load, not a parameter; its other components are
    sp2 = design.parameter_space(coarse("three-roller-tension")[0], "roller 1,roller 2,roller 3:dz,roller 3:ax")
    assert "roller 2:dx" not in sp2.labels() and {"roller 2:dy", "roller 2:ax"} <= set(sp2.labels())
    assert sp2.size == 5 + 4 + 2
    assert any(jc == (1, "dx") and "force/torque-loaded" in why for jc, why in sp2.structural)


def test_study_rejects_bad_metric_and_time(loaded2d):
    model2d, opts = loaded2d
    with pytest.raises(ValueError, match="unknown"):
        design.make_study(model2d, "lateral_avg", opts)
    with pytest.raises(ValueError, match="t_eval"):
        design.make_study(model2d, "lateral_rms", opts, t_eval=0.0)
    model1, opts1 = load("two-roller-1d")
    with pytest.raises(ValueError, match="2D scene"):
        design.make_study(model1, "lateral_max", opts1, t_eval=0.05)


@pytest.mark.slow
def test_metrics_are_zero_for_the_aligned_machine_and_match_their_definitions(study):
    du, dv = design.tracer_deviation(study, jnp.zeros(study.space.size))
    k = study.n_steps - 1
    assert np.isclose(float(design.metric_value(study, jnp.zeros(4))), float(jnp.sqrt(jnp.mean(dv[k] ** 2))), rtol=1e-12)
    aligned = design.make_study(study.model.replace(chi_static=jnp.zeros_like(study.base)), "lateral_max",
                                study.options, t_eval=study.t_eval, components="roller 2:rotation")
    assert float(design.metric_value(aligned, jnp.zeros(2))) == 0.0
    peak = design.make_study(study.model, "lateral_peak", study.options, t_eval=study.t_eval,
                             components="roller 2:rotation")
    dv2 = design.tracer_deviation(peak, jnp.zeros(2))[1]
    assert np.isclose(float(design.metric_value(peak, jnp.zeros(2))), float(jnp.max(jnp.abs(dv2[-peak.window:]))))
    assert float(design.metric_value(peak, jnp.zeros(2), smooth=True)) >= float(design.metric_value(peak, jnp.zeros(2)))


# ----------------------------------------------------------------------------- gradients


def _fd_check(study, theta, h):
    value, grad = design.value_and_gradient(study, theta)
    P = study.space.size
    pts = jnp.concatenate([theta + h * jnp.eye(P), theta - h * jnp.eye(P)])
    vals = jax.vmap(lambda t: design.metric_value(study, t))(pts)
    fd = (vals[:P] - vals[P:]) / (2 * h)
    np.testing.assert_allclose(np.asarray(grad), np.asarray(fd), rtol=1e-6, atol=1e-6 * float(jnp.max(jnp.abs(fd))))
    return grad


@pytest.mark.slow
def test_gradient_2d_drive_idle_tension_translations_and_rotations():
    """Roller 1 drives, roller 2 is a tension roller (pulled along x), roller 3 idles.

    Slow (three compiled 2D programs of its own). Fast: the design gradient against central
    differences (test_gradient_1d_translations) and against the forward-mode Jacobian in 2D
    (test_jacobian_forward_matches_the_reverse_gradient); the 2D gradient through drive, tension
    and idle rollers against central differences (test_grad, case 2d-tension); the tension
    roller's x out of the parameters (test_parameter_space_excludes_structural_zeros)."""
    model, opts = coarse("three-roller-tension")
    model = model.replace(chi_static=model.chi_static.at[jnp.array([1, 9, 14])].set(jnp.array([1e-3, 2e-4, 5e-4])))
    st = design.make_study(model, "lateral_rms", opts, t_eval=0.16, components="roller 1,roller 2,roller 3:dz,roller 3:ax")
    assert "roller 2:dx" not in st.space.labels()  # the load sets it
    grad = _fd_check(st, jnp.zeros(st.space.size), 1e-3)
    assert float(jnp.min(jnp.abs(grad))) > 0


@pytest.mark.slow
def test_gradient_1d_translations():
    model, opts = load("two-roller-1d-idle-translated")
    st = design.make_study(model, "longitudinal_rms", opts, t_eval=0.1)
    _fd_check(st, jnp.zeros(st.space.size), 1e-4)


@pytest.mark.slow
def test_jacobian_forward_matches_the_reverse_gradient(study):
    """Forward-mode Jacobian J of the response r and the reverse-mode gradient of RMS(r) agree
    through the chain rule: ∇ = Jᵀ r / (n · RMS)."""
    r0, J = design.response_jacobian(study, mode="forward")
    report = design.sensitivity_report(study, repeat=1)
    grad = np.array([p.gradient for p in report.parameters])
    rms = np.sqrt(np.mean(r0**2))
    ref = J.T @ r0 / (len(r0) * rms)
    np.testing.assert_allclose(grad, ref, rtol=1e-9, atol=1e-9 * np.abs(ref).max())
    assert np.isclose(report.value_um, rms, rtol=1e-12)
    assert report.gradient["roller 1"].rotation_um_per_mrad == (0.0, 0.0, 0.0)
    assert {z.component for z in report.structural_zero} == {"roller 1:az", "roller 2:az", "roller 3:az"}


# ----------------------------------------------------------------------------- tolerance box


def test_box_of_an_exactly_linear_model_is_analytic():
    """One response row r = a·θ: max Σ w log h s.t. Σ |a_k| h_k ≤ L gives h_k = w_k L / (Σw |a_k|)."""
    a = np.array([2.0, -0.5, 8.0, 1.0])
    w = np.array([1.0, 2.0, 1.0, 0.5])
    lin = linear_box.LinearResponse(np.zeros(1), a[None, :], "max")
    h = linear_box.optimise_box(lin, 20.0, w, h_max=100.0)
    np.testing.assert_allclose(h, w * 20.0 / (w.sum() * np.abs(a)), rtol=2e-3)
    # with the cap h ≤ 5 active on component 1, the others share what is left
    h = linear_box.optimise_box(lin, 20.0, w, h_max=5.0)
    rest = np.array([0, 2, 3])
    np.testing.assert_allclose(h[rest], w[rest] * 17.5 / (w[rest].sum() * np.abs(a[rest])), rtol=2e-3)
    assert np.isclose(linear_box.worst_case(lin, h), 20.0, rtol=1e-9)


def test_box_with_several_rows_and_rms_matches_scipy():
    from scipy.optimize import minimize

    rng = np.random.default_rng(3)
    J = rng.normal(size=(6, 3))
    r0 = 0.5 * rng.normal(size=6)
    for kind in ("max", "rms"):
        lin = linear_box.LinearResponse(r0, J, kind)
        h = linear_box.optimise_box(lin, 10.0)
        cons = {"type": "ineq", "fun": lambda y: 10.0 - linear_box.worst_case(lin, np.exp(y))}
        ref = minimize(lambda y: -np.sum(y), np.log(h * 0.5), constraints=[cons], method="SLSQP",
                       bounds=[(None, np.log(linear_box.H_MAX))] * 3, options={"ftol": 1e-12, "maxiter": 500})
        assert np.sum(np.log(h)) >= -ref.fun - 2e-3
        assert linear_box.worst_case(lin, h) <= 10.0 + 1e-9


def test_box_with_thousands_of_rows_satisfies_the_optimality_conditions():
    """A max-type box over 3000 response rows: the Karush-Kuhn-Tucker conditions hold at the result
    (w/h a non-negative combination of the active rows, by NNLS), and another start of the
    Lagrangian gives the same box."""
    from scipy.optimize import nnls

    rng = np.random.default_rng(7)
    J = rng.normal(size=(3000, 6)) * np.array([1.0, 3.0, 0.3, 10.0, 1.0, 0.05])
    r0 = rng.normal(size=3000)
    lin = linear_box.LinearResponse(r0, J, "max")
    w = np.array([1.0, 1.0, 2.0, 1.0, 0.5, 1.0])
    h = linear_box.optimise_box(lin, 20.0, w)
    other = linear_box.optimise_box(lin, 20.0, w, outer=3, inner=20)
    np.testing.assert_allclose(other, h, rtol=1e-6)
    g = np.abs(r0) + np.abs(J) @ h
    assert np.isclose(g.max(), 20.0, rtol=1e-9)
    active, free = np.flatnonzero(g > 20.0 * (1 - 1e-6)), h < linear_box.H_MAX * (1 - 1e-9)
    lam, residual = nnls(np.abs(J)[active][:, free].T, (w / h)[free])
    assert residual <= 1e-6 * np.linalg.norm((w / h)[free])


def test_rss_stackup_of_one_row():
    lin = linear_box.LinearResponse(np.zeros(1), np.array([[3.0, 4.0]]), "max")
    assert np.isclose(linear_box.rss_stackup(lin, [1.0, 1.0]).three_sigma_um, 15.0)


@pytest.mark.slow
def test_box_on_the_default_scene_is_verified_by_full_runs():
    """The full-size scene (slow). Fast: the same box and verification on the coarse scene,
    through the CLI (test_cli_design.py::test_tolerance_json)."""
    model, opts = load("three-roller")  # the aligned nominal machine, N = 3762
    st = design.make_study(model, "lateral_max", opts, t_eval=0.1, components="roller 2:rotation,roller 3:dz")
    res = design.tolerance_box(st, 20.0, n_random=2, n_corners=2)
    assert res.verified and 0.97 * 20 <= res.worst_case_um <= 20.0
    full = [row.full_um for row in res.verification]
    assert max(full) == res.worst_case_um
    assert res.binding and set(res.binding) <= set(st.space.labels())
    # the box is around the scene's own misalignment, half-widths non-negative and finite
    assert np.all(res.half_widths >= 0) and np.all(np.isfinite(res.half_widths))


# ----------------------------------------------------------------------------- yield


def _dist(study, kinds=("normal", "uniform", "normal", "uniform"), scales=(0.2, 0.3, 0.05, 0.05)):
    return sampling.Distribution(tuple(study.space.labels()), kinds[: study.space.size], scales[: study.space.size])


@pytest.mark.slow
def test_monte_carlo_equals_a_brute_force_loop(study, metric_fn):
    dist = _dist(study)
    limit = 1.1 * float(design.metric_value(study, jnp.zeros(4)))
    mc = design.monte_carlo(study, dist, 12, limit, seed=5, chunk=CHUNK)  # two chunks, the last padded
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
def limit_13(study):
    """A limit 1.3 times the nominal metric, and a 400-sample Monte Carlo against it (shared by
    the FORM / importance-sampling and the OpenTURNS comparisons)."""
    limit = 1.3 * float(design.metric_value(study, jnp.zeros(4)))
    return limit, design.monte_carlo(study, _dist(study), 400, limit, seed=11, chunk=CHUNK)


@pytest.mark.slow
def test_form_and_importance_sampling_agree_with_monte_carlo(study, limit_13):
    dist = _dist(study)
    limit, mc = limit_13
    f = design.form(study, dist, limit)
    assert f.converged and f.beta > 0
    assert np.isclose(float(design.metric_value(study, jnp.asarray(f.theta_star))), limit, rtol=1e-6)
    is_ = design.importance_sampling(study, dist, limit, f.u_star, n=400, chunk=CHUNK)
    assert is_.ci95[0] - 0.03 <= mc.yield_ <= is_.ci95[1] + 0.03


@pytest.mark.slow
def test_sweep_store_resumes_and_extends(study, tmp_path):
    dist = _dist(study)
    limit = 1.1 * float(design.metric_value(study, jnp.zeros(4)))
    out = tmp_path / "sweep.zarr"
    first = design.run_sweep(study, dist, 8, limit, chunk=CHUNK, out=out, with_form=False)
    again = design.run_sweep(study, dist, 16, limit, chunk=CHUNK, out=out, with_form=False)
    fresh = design.run_sweep(study, dist, 16, limit, chunk=CHUNK, with_form=False)
    np.testing.assert_allclose(again.metric_values, fresh.metric_values, rtol=1e-12)
    np.testing.assert_allclose(again.metric_values[:8], first.metric_values, rtol=1e-12)
    ds = load_sweep(out)
    assert ds.sizes["config"] == 16 and ds.sizes["tracer"] == study.ref_u.shape[1]
    with pytest.raises(ValueError, match="another sweep"):
        design.run_sweep(study, dist, 8, 2 * limit, chunk=CHUNK, out=out, with_form=False)


@pytest.mark.slow
def test_monte_carlo_and_form_match_openturns(study, metric_fn, limit_13):
    """The same limit state (metric > limit under the same input laws) through OpenTURNS' FORM
    (Abdo–Rackwitz) and its Monte Carlo."""
    ot = pytest.importorskip("openturns")
    dist = _dist(study)
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


@pytest.mark.parametrize("kind", ["max", "rms"])
@pytest.mark.parametrize("offset", [0.0, 0.7])
def test_worst_case_equals_enumerating_every_corner(kind, offset):
    import itertools

    rng = np.random.default_rng(1)
    J = rng.normal(size=(7, 5))
    lin = linear_box.LinearResponse(offset * rng.normal(size=7), J, kind)
    h = rng.uniform(0.1, 1.0, size=5)
    corners = np.array(list(itertools.product((-1.0, 1.0), repeat=5)))
    brute = max(lin.metric(c * h) for c in corners)
    signs, vals = linear_box.worst_corners(lin, h, 3)
    assert np.isclose(linear_box.worst_case(lin, h), brute, rtol=1e-12)
    assert np.isclose(lin.metric(signs[0] * h), brute, rtol=1e-12) and np.all(np.diff(vals) <= 0)


def test_a_diverging_reference_is_named_with_or_without_the_jacobian():
    """The aligned reference that diverges (a NaN in the roller masses) raises the run's own
    error, whether the study runs it plainly or as the primal of its Jacobian."""
    model, opts = load(jb.load_scene("two-roller-1d"))
    bad = model.replace(M_roller=model.M_roller.at[-1].set(jnp.nan))
    for jacobian in (False, True):
        with pytest.raises(jb.NonFiniteStateError, match="diverged"):
            design.make_study(bad, "longitudinal_max", opts.replace(n_steps=4, solver=jb.make_solver()), jacobian=jacobian)


def test_a_study_with_its_jacobian_runs_the_programs_of_one_without():
    """``make_study(..., jacobian=True)`` gives the study and, beside it, its linear deviations: the
    study is the plain one (the same pytree), so the programs that run configurations are traced
    and compiled once for both, and the linear response read from the deviations is the one a
    run of the plain study gives."""
    from helpers import counting_compiles

    model, opts = load(jb.load_scene("two-roller-1d"))
    opts = opts.replace(n_steps=4, solver=jb.make_solver())
    plain = design.make_study(model, "longitudinal_max", opts)
    study, linear = design.make_study(model, "longitudinal_max", opts, jacobian=True)
    assert isinstance(study, design.Study) and isinstance(linear, design.LinearDeviation)
    assert jax.tree.structure(study) == jax.tree.structure(plain)
    assert linear.d_u_um_per_theta.shape == study.ref_u.shape + (study.space.size,)
    thetas = np.full((2, study.space.size), 0.01)
    first = design.evaluate_metric(plain, thetas, chunk=2)
    with counting_compiles() as events:
        again = design.evaluate_metric(study, thetas, chunk=2)
    assert events == [] and again == pytest.approx(first, rel=1e-12)
    r0, J = design.response_jacobian(plain)
    r0_lin, J_lin = design.response_jacobian(study, linear=linear)
    np.testing.assert_allclose(J_lin, J, rtol=0, atol=1e-9 * np.abs(J).max())
    np.testing.assert_allclose(r0_lin, r0, rtol=0, atol=1e-9 * np.abs(J).max())
    with pytest.raises(ValueError, match="θ = 0 only"):
        design.response_jacobian(study, np.zeros(study.space.size), linear=linear)


def test_study_and_its_values_in_one_batch_equal_the_reference_run_and_single_runs(study, metric_fn, model2d):
    """make_study_at: the aligned reference and the configurations as one vmap batch give the
    study make_study builds (its reference run apart) and the metric of a run per configuration
    (on the misaligned base: the run at θ = 0 is not the reference)."""
    from jaxbelt.design.study import make_study_at

    thetas = np.array([[0.0, 0.0, 0.0, 0.0], [0.05, -0.1, 0.2, -0.3]])
    st, values = make_study_at(model2d, "lateral_rms", thetas, study.options, t_eval=0.24,
                               components="roller 2:rotation,roller 3:dx,roller 3:dz")
    assert st.n_steps == study.n_steps and st.window == study.window and st.space == study.space
    assert np.allclose(st.ref_u, study.ref_u, rtol=0, atol=1e-15) and np.allclose(st.ref_v, study.ref_v, rtol=0, atol=1e-15)
    single = [float(metric_fn(jnp.asarray(t))) for t in thetas]
    assert values.shape == (2,) and single[0] > 0 and values == pytest.approx(single, rel=1e-9)


def test_response_is_linear_in_small_misalignments(study):
    """What the tolerance box relies on: r(θ) = r0 + J θ to 1e-6 relative at 0.05 mm / mrad."""
    r0, J = design.response_jacobian(study)
    scale = 0.05 * np.max(np.abs(J))  # components the metric hardly feels are held to round-off of the others
    for k in range(study.space.size):
        theta = np.zeros(study.space.size)
        theta[k] = 0.05
        dr = design.response_jacobian(study, theta)[0] - r0  # r(θ), from the same compiled program
        assert np.max(np.abs(dr - J @ theta)) <= 1e-6 * max(np.max(np.abs(J @ theta)), 1e-3 * scale)
