"""The DAE assembly of :mod:`jaxbelt.assembly` on a coarse pre-tensioned 1D belt (22 node columns)
against a numpy dense assembly written from the row rules: free-belt rows ``[K_f, 0]``, no-slip rows
``[I, −R]``, dynamic roller rows ``[Rᵀ K_f, 0]`` and ``[Rᵀ diag(m), M_r]``, prescribed roller rows
``[0, I]``; the right-hand side row by row; the lumped masses (half, or a quarter in 2D, of each
adjacent element's) against hand sums; the reduced (on-roller) form of ``R`` against the full one."""

import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt.assembly import (belt_force_on_rollers, dae_apply, dae_matrices, dae_rhs, free_belt_matvec,
                              free_belt_stencil, generalised_belt_force, nodal_masses, roller_R,
                              roller_stiffness_rows, roller_times, step_matrix)
from helpers import load, scene_with


@pytest.fixture(scope="module")
def model():
    m = load(scene_with(lambda d: d["mesh"].update(roller_elements=[5, 5], free_elements=[6, 6]),
                        "two-roller-1d-pretension"))[0]
    assert float(jnp.abs(m.f0).max()) > 0  # the pre-tension rows are exercised
    return m


def _dense_Kf(model):
    """The cyclic block-tridiagonal free-belt stiffness (n b × n b)."""
    Kd, Kl, Ku = (np.asarray(a) for a in (model.K_diag, model.K_lower, model.K_upper))
    n, b = Kd.shape[:2]
    K = np.zeros((n * b, n * b))
    for i in range(n):
        r = slice(i * b, (i + 1) * b)
        K[r, r] += Kd[i]
        K[r, ((i - 1) % n) * b:((i - 1) % n + 1) * b] += Kl[i]
        K[r, ((i + 1) % n) * b:((i + 1) % n + 1) * b] += Ku[i]
    return K


def _perturbed_masses(model, seed=0):
    return model.m_e0 * (1.0 + 0.3 * jnp.asarray(np.random.default_rng(seed).random(model.m_e0.shape)))


def test_nodal_masses_are_half_of_each_adjacent_element_and_keep_the_total(model):
    m_e = np.asarray(_perturbed_masses(model))
    m = np.asarray(nodal_masses(model, jnp.asarray(m_e)))
    assert m.shape == (model.n_xi, model.block)
    np.testing.assert_allclose(m[:, 0], 0.5 * (m_e + np.r_[m_e[-1], m_e[:-1]]), rtol=1e-15)
    np.testing.assert_allclose(m.sum(), m_e.sum(), rtol=1e-14)


def test_two_d_nodal_masses_are_a_quarter_of_each_adjacent_quad_on_u_and_v():
    stand_in = types.SimpleNamespace(block=6)
    m_e = np.arange(1.0, 9.0).reshape(4, 2)  # 4 element columns × 2 element rows: 3 node rows
    m = np.asarray(nodal_masses(stand_in, jnp.asarray(m_e)))
    assert m.shape == (4, 6)
    want = np.zeros((4, 3))
    for i in range(4):
        for r in range(2):
            for ci in (i, (i + 1) % 4):  # the quad's four corner nodes
                for rr in (r, r + 1):
                    want[ci, rr] += m_e[i, r] / 4
    np.testing.assert_allclose(m[:, 0::2], want, rtol=1e-15)
    np.testing.assert_allclose(m[:, 1::2], want, rtol=1e-15)


def test_free_belt_product_and_roller_stiffness_rows_equal_dense_products(model):
    K = _dense_Kf(model)
    n, b, q = model.R.shape
    u = np.random.default_rng(1).standard_normal((n, b))
    np.testing.assert_allclose(np.asarray(free_belt_matvec(model, jnp.asarray(u))).ravel(), K @ u.ravel(),
                               rtol=1e-12, atol=1e-9 * np.abs(K).max())
    R = np.asarray(model.R).reshape(n * b, q)
    rows = np.asarray(roller_stiffness_rows(model.R, model.K_diag, model.K_lower, model.K_upper))
    np.testing.assert_allclose(rows.transpose(1, 0, 2).reshape(q, n * b), R.T @ K, rtol=1e-12,
                               atol=1e-9 * np.abs(K).max())
    f = np.random.default_rng(2).standard_normal((n, b))
    np.testing.assert_allclose(np.asarray(generalised_belt_force(model.R, jnp.asarray(f))), R.T @ f.ravel(),
                               rtol=1e-13, atol=1e-15)


def test_dae_matrices_follow_the_row_rules(model):
    m_e = _perturbed_masses(model)
    K, M = jax.jit(dae_matrices)(model, m_e)  # one program, not op by op
    n, b, q = model.R.shape
    nb = n * b
    con = np.asarray(model.is_constraint).ravel()
    dyn = np.asarray(model.dynamic)
    R = np.asarray(model.R).reshape(nb, q)
    Kf = _dense_Kf(model)
    m = np.asarray(nodal_masses(model, m_e)).ravel()
    K_ref, M_ref = np.zeros((nb + q, nb + q)), np.zeros((nb + q, nb + q))
    for i in range(nb):
        if con[i]:
            K_ref[i, i], K_ref[i, nb:] = 1.0, -R[i]
        else:
            K_ref[i, :nb], M_ref[i, i] = Kf[i], m[i]
    for c in range(q):
        if dyn[c]:
            K_ref[nb + c, :nb] = R[:, c] @ Kf
            M_ref[nb + c, :nb], M_ref[nb + c, nb + c] = R[:, c] * m, float(model.M_roller[c])
        else:
            K_ref[nb + c, nb + c] = 1.0
    scale = np.abs(Kf).max()
    np.testing.assert_allclose(np.asarray(K.to_dense()), K_ref, rtol=1e-12, atol=1e-12 * scale)
    np.testing.assert_allclose(np.asarray(M.to_dense()), M_ref, rtol=1e-14, atol=1e-18)
    assert con.any() and (~con).any() and dyn.any() and (~dyn).any()
    dt = 0.004
    A = jax.jit(step_matrix)(model, m_e, model.R, dt).to_dense()
    np.testing.assert_allclose(np.asarray(A), M_ref + dt ** 2 * K_ref, rtol=1e-12, atol=1e-12 * dt ** 2 * scale)


def test_dae_rhs_follows_the_row_rules(model):
    n, b, q = model.R.shape
    rng = np.random.default_rng(3)
    u_prev, chi_prev = rng.standard_normal((n, b)) * 1e-4, rng.standard_normal(q) * 1e-3
    dt = 0.004
    F_b, F_r = dae_rhs(model, jnp.asarray(u_prev), jnp.asarray(chi_prev), dt)
    R, f0 = np.asarray(model.R), np.asarray(model.f0)
    con = np.asarray(model.is_constraint)
    np.testing.assert_allclose(np.asarray(F_b), np.where(con, u_prev - np.einsum("nbq,q->nb", R, chi_prev), -f0),
                               rtol=1e-13, atol=1e-18)
    dyn, is_az = np.asarray(model.dynamic), np.asarray(model.is_az)
    want = np.where(dyn, np.asarray(model.Q_ext) - R.reshape(n * b, q).T @ f0.ravel(),
                    np.asarray(model.chi_static) + np.where(is_az, chi_prev, 0.0) + np.asarray(model.omega) * dt)
    np.testing.assert_allclose(np.asarray(F_r), want, rtol=1e-13, atol=1e-15)
    drive = int(np.argmax(np.abs(np.asarray(model.omega))))  # the drive turns by ω Δt from its last angle
    np.testing.assert_allclose(float(F_r[drive]), chi_prev[drive] + float(model.omega[drive]) * dt, rtol=1e-14)


def test_matrix_free_products_equal_the_assembled_matrices(model):
    m_e = _perturbed_masses(model)
    K, M = jax.jit(dae_matrices)(model, m_e)
    rng = np.random.default_rng(4)
    xb, xr = jnp.asarray(rng.standard_normal((model.n_xi, model.block))), jnp.asarray(rng.standard_normal(4))
    (kb, kr), (mb, mr) = dae_apply(model, m_e, model.R, xb, xr)
    x = np.r_[np.asarray(xb).ravel(), np.asarray(xr)]
    np.testing.assert_allclose(np.r_[np.asarray(kb).ravel(), np.asarray(kr)], np.asarray(K.to_dense()) @ x,
                               rtol=1e-11, atol=1e-9)
    np.testing.assert_allclose(np.r_[np.asarray(mb).ravel(), np.asarray(mr)], np.asarray(M.to_dense()) @ x,
                               rtol=1e-12, atol=1e-15)


def test_on_roller_form_of_R_gives_the_same_products(model):
    if model.contact_columns is None:
        pytest.skip("the model does not know its roller columns")
    u = jnp.zeros((model.n_xi, model.block))
    R_full, R_on = roller_R(model, u), roller_R(model, u, on_rollers=True)
    assert R_on.shape[0] == len(model.contact_columns) < model.n_xi
    chi = jnp.asarray(np.random.default_rng(5).standard_normal(model.n_roller_dofs))
    np.testing.assert_allclose(np.asarray(roller_times(model, R_on, chi)), np.asarray(roller_times(model, R_full, chi)),
                               rtol=1e-15)
    f = jnp.asarray(np.random.default_rng(6).standard_normal((model.n_xi, model.block)))
    np.testing.assert_allclose(np.asarray(belt_force_on_rollers(model, R_on, f)),
                               np.asarray(belt_force_on_rollers(model, R_full, f)), rtol=1e-13)
    assert free_belt_stencil(model) is None  # 1D: no stencil
