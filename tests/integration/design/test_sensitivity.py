"""Design gradients and Jacobians (jaxbelt.design.sensitivity) against differences and each other."""

import jax
import jax.numpy as jnp
import numpy as np
from helpers import coarse, load

from jaxbelt import design


def _fd_check(study, theta, h):
    value, grad = design.value_and_gradient(study, theta)
    P = study.space.size
    pts = jnp.concatenate([theta + h * jnp.eye(P), theta - h * jnp.eye(P)])
    vals = jax.vmap(lambda t: design.metric_value(study, t))(pts)
    fd = (vals[:P] - vals[P:]) / (2 * h)
    np.testing.assert_allclose(np.asarray(grad), np.asarray(fd), rtol=1e-6, atol=1e-6 * float(jnp.max(jnp.abs(fd))))
    return grad


def test_gradient_2d_drive_idle_tension_translations_and_rotations():
    """Roller 1 drives, roller 2 is a tension roller (pulled along x), roller 3 idles.

    Slow (three compiled 2D programs of its own). Fast: the design gradient against central
    differences (test_gradient_1d_translations) and against the forward-mode Jacobian in 2D
    (test_jacobian_forward_matches_the_reverse_gradient); the 2D gradient through drive, tension
    and idle rollers against central differences (test_grad, case 2d-tension); the tension
    roller's x out of the parameters (test_study.py::test_parameter_space_excludes_structural_zeros)."""
    model, opts = coarse("three-roller-tension")
    model = model.replace(chi_static=model.chi_static.at[jnp.array([1, 9, 14])].set(jnp.array([1e-3, 2e-4, 5e-4])))
    st = design.make_study(model, "lateral_rms", opts, t_eval=0.16, components="roller 1,roller 2,roller 3:dz,roller 3:ax")
    assert "roller 2:dx" not in st.space.labels()  # the load sets it
    grad = _fd_check(st, jnp.zeros(st.space.size), 1e-3)
    assert float(jnp.min(jnp.abs(grad))) > 0


def test_gradient_1d_translations():
    model, opts = load("two-roller-1d-idle-translated")
    st = design.make_study(model, "longitudinal_rms", opts, t_eval=0.1)
    _fd_check(st, jnp.zeros(st.space.size), 1e-4)


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


def test_response_is_linear_in_small_misalignments(study):
    """What the tolerance box relies on: r(θ) = r0 + J θ to 1e-6 relative at 0.05 mm / mrad."""
    r0, J = design.response_jacobian(study)
    scale = 0.05 * np.max(np.abs(J))  # components the metric hardly feels are held to round-off of the others
    for k in range(study.space.size):
        theta = np.zeros(study.space.size)
        theta[k] = 0.05
        dr = design.response_jacobian(study, theta)[0] - r0  # r(θ), from the same compiled program
        assert np.max(np.abs(dr - J @ theta)) <= 1e-6 * max(np.max(np.abs(J @ theta)), 1e-3 * scale)

