"""The steady solves' mass-transport preconditioner (:mod:`jaxbelt.steady.preconditioner`) on a coarse
``two-roller-1d`` belt, against a numpy assembly of ``M = I − Cⁿ + 𝟙𝟙ᵀ/n`` from the upwind mass
flux written out by hand (drive speed from the scene file, ``s = VΔt``): its solve equals the dense
solve, its transpose is the adjoint, it keeps the ``m_e0``-weighted total mass, and
:func:`preconditioned` touches the mass block only."""

import jax
import jax.flatten_util
import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt.steady import preconditioner
from jaxbelt.steady.preconditioner import preconditioned
from helpers import builtin_dict, load, scene_with

N_STEPS = 7
mass_transport_preconditioner = jax.jit(preconditioner.mass_transport_preconditioner, static_argnums=2)  # one program


@pytest.fixture(scope="module")
def coarse_1d():
    model, options = load(scene_with(lambda d: d["mesh"].update(roller_elements=[5, 5], free_elements=[6, 6])))
    return model, options.dt


def _dense_M(ell, shift, n):
    """Element ``i`` gains ``(s/ℓ_{i−1}) m_{i−1}`` across its left node and loses ``(s/ℓ_i) m_i``
    across its right one (shift rule, uniform upwind weights)."""
    k = len(ell)
    C = np.zeros((k, k))
    for i in range(k):
        C[i, i] = 1.0 - shift / ell[i]
        C[i, i - 1] += shift / ell[i - 1]
    return np.eye(k) - np.linalg.matrix_power(C, n) + 1.0 / k


def test_solve_equals_the_dense_solve_of_the_hand_assembled_transport(coarse_1d):
    model, dt = coarse_1d
    speed = [r["speed_m_s"] for r in builtin_dict()["roller"] if r["role"] == "drive"][0]
    ell, m0 = np.asarray(model.ell), np.asarray(model.m_e0)
    M = _dense_M(ell, speed * dt, N_STEPS)
    pre = mass_transport_preconditioner(model, dt, N_STEPS)
    r = np.random.default_rng(0).standard_normal(len(ell))
    np.testing.assert_allclose(np.asarray(pre.solve(jnp.asarray(r))), np.linalg.solve(M, r * m0) / m0, rtol=1e-10)
    R = np.random.default_rng(1).standard_normal((len(ell), 3))  # several rows at once
    np.testing.assert_allclose(np.asarray(pre.solve(jnp.asarray(R))), np.linalg.solve(M, R * m0[:, None]) / m0[:, None],
                               rtol=1e-10)
    assert np.abs(np.linalg.solve(M, r * m0) / m0 - r).max() > 1e-3  # not the identity: the check can fail


def test_transpose_solve_is_the_adjoint(coarse_1d):
    model, dt = coarse_1d
    pre = mass_transport_preconditioner(model, dt, N_STEPS)
    rng = np.random.default_rng(2)
    a, b = (jnp.asarray(rng.standard_normal(model.ell.shape[0])) for _ in range(2))
    np.testing.assert_allclose(float(pre.solve(a) @ b), float(a @ pre.solve(b, transpose=True)), rtol=1e-12)


def test_solve_keeps_the_mass_weighted_total(coarse_1d):
    """Transport conserves mass, so ``𝟙ᵀ M = 𝟙ᵀ`` and ``Σ m_e0 (M⁻¹ r) = Σ m_e0 r`` in scaled units."""
    model, dt = coarse_1d
    pre = mass_transport_preconditioner(model, dt, 40)
    r = jnp.asarray(np.random.default_rng(3).standard_normal(model.ell.shape[0]))
    m0 = np.asarray(model.m_e0)
    np.testing.assert_allclose(float(m0 @ np.asarray(pre.solve(r))), float(m0 @ np.asarray(r)), rtol=1e-10)


def test_a_belt_that_does_not_move_gets_the_identity(coarse_1d):
    model, _ = coarse_1d
    pre = mass_transport_preconditioner(model, 0.0, N_STEPS)
    r = jnp.asarray(np.random.default_rng(4).standard_normal(model.ell.shape[0]))
    np.testing.assert_allclose(np.asarray(pre.solve(r)), np.asarray(r), rtol=1e-14)


def test_preconditioned_maps_the_mass_block_only_of_plain_and_walking_unknowns(coarse_1d):
    model, dt = coarse_1d
    assert preconditioned(None, (jnp.zeros(2),)) is None
    pre = mass_transport_preconditioner(model, dt, N_STEPS)
    n = model.ell.shape[0]
    rng = np.random.default_rng(5)
    fields = tuple(jnp.asarray(rng.standard_normal(s)) for s in [(n, 1), (n, 1), (4,), (4,), (n,), (2,)])
    for template in (fields, (fields, jnp.asarray(0.25))):
        flat, unravel = jax.flatten_util.ravel_pytree(template)
        out = unravel(preconditioned(pre, template)(flat))
        got, want = (out[0], template[0]) if len(template) == 2 else (out, template)
        for k in (0, 1, 2, 3, 5):
            np.testing.assert_array_equal(np.asarray(got[k]), np.asarray(want[k]))
        np.testing.assert_allclose(np.asarray(got[4]), np.asarray(pre.solve(want[4])), rtol=1e-14)
        if len(template) == 2:
            assert float(out[1]) == 0.25
    flat, unravel = jax.flatten_util.ravel_pytree(fields)
    out = unravel(preconditioned(pre, fields, transpose=True)(flat))
    np.testing.assert_allclose(np.asarray(out[4]), np.asarray(pre.solve(fields[4], transpose=True)), rtol=1e-14)
