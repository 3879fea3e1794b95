"""The tolerance study (jaxbelt.design.study): its parameters, rejections, Jacobian and batched values."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import coarse, load

import jaxbelt as jb
from jaxbelt import design


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
    assert st.options.n_steps == study.options.n_steps and st.window == study.window and st.space == study.space
    assert np.allclose(st.ref_u, study.ref_u, rtol=0, atol=1e-15) and np.allclose(st.ref_v, study.ref_v, rtol=0, atol=1e-15)
    single = [float(metric_fn(jnp.asarray(t))) for t in thetas]
    assert values.shape == (2,) and single[0] > 0 and values == pytest.approx(single, rel=1e-9)

