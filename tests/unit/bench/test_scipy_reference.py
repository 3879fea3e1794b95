"""The numpy + SciPy step (:class:`jaxbelt.bench.scipy_reference.ScipyBelt`) against jaxbelt's own
assembly and transport on a tiny hand-made 2D model (6 node columns of 2 rows, the first three on a
roller with a prescribed translation, a free lateral translation and a driven rotation): the lumped
masses, the lagged roller kinematics, the stiffness product, the step matrix ``M + Δt² K``, the
equilibrated SuperLU solve against a dense solve, one whole Backward-Euler step with the shift
transport (the belt moving forward and backward), and the factor kept from the first step."""

from types import SimpleNamespace

import jax
import numpy as np
import pytest

from jaxbelt.assembly import dae_apply, dae_matrices, dae_rhs, nodal_masses, roller_R
from jaxbelt.bench import scipy_reference
from jaxbelt.bench.scipy_reference import ScipyBelt
from jaxbelt.linalg import join
from jaxbelt.transport import transport_step_with_weights

N, ETA, Q = 6, 2, 3
B = 2 * ETA
DT = 2e-3
rng = np.random.default_rng(7)
on = np.array([True, True, True, False, False, False])
con = np.repeat(on[:, None], B, axis=1)
R0 = np.where(con[:, :, None], rng.standard_normal((N, B, Q)), 0.0)
MODEL = SimpleNamespace(
    kind="2d", n_xi=N, n_eta=ETA, block=B, contact_columns=None, lateral_transport=False,
    K_diag=rng.standard_normal((N, B, B)) + 12.0 * np.eye(B), K_lower=rng.standard_normal((N, B, B)),
    K_upper=rng.standard_normal((N, B, B)), R=R0, R_dz=np.where(con[:, :, None], rng.standard_normal((N, B, Q)), 0.0),
    is_constraint=con, dynamic=np.array([False, True, False]), is_az=np.array([False, False, True]),
    f0=0.1 * rng.standard_normal((N, B)), Q_ext=rng.standard_normal(Q), M_roller=np.array([1.0, 0.5, 1.0]),
    chi_static=np.array([1e-4, 0.0, 0.0]), omega=np.array([0.0, 0.0, 10.0]), ell=np.full(N, 0.01),
    node_roller=np.where(on, 0, -1))
OFFSET = 1e-5 * rng.standard_normal((N, B))  # the exact static surface motion minus its linearisation


@pytest.fixture(scope="module")
def belt():
    with pytest.MonkeyPatch.context() as mp:  # the surface offset the model would compute, given
        mp.setattr(scipy_reference, "roller_surface_displacement",
                   lambda model, chi, R: np.einsum("nbq,q->nb", R, chi) + OFFSET)
        return ScipyBelt(MODEL, DT)


def _state(seed, forward=True):
    r = np.random.default_rng(seed)
    u = 1e-4 * r.standard_normal((N, B))
    u[:, 0::2] += 2e-3 if forward else -2e-3  # the belt moved ~0.2 elements along x
    return [u, 1e-3 * r.standard_normal((N, B)), np.array([1e-4, 2e-5, 0.3]), 1e-2 * r.standard_normal(Q),
            1.0 + 0.2 * r.random((N, ETA - 1))]


@jax.jit
def _jaxbelt_pieces(u, ud, chi, chid, m_e):
    """jaxbelt's step matrices (dense), right-hand side and stiffness products at the lagged ``R``."""
    R = roller_R(MODEL, u)
    K, M = dae_matrices(MODEL, m_e, R)
    F = join(*dae_rhs(MODEL, u, chi, DT, R))
    return R, K.to_dense(), M.to_dense(), F


@jax.jit
def _jaxbelt_transport(u, ud, chi, m_e):
    return transport_step_with_weights(MODEL, u, ud, chi, m_e, static_offset=OFFSET)[:4]


def _dense_step(state):
    """``(x₁, ẋ₁)`` of the Backward-Euler step ``(M + Δt² K) ẍ = F − K (x + Δt ẋ)`` by a dense solve."""
    u, ud, chi, chid, m_e = state
    _, K, M, F = (np.asarray(a) for a in _jaxbelt_pieces(*state))
    x0, v0 = np.concatenate([u.ravel(), chi]), np.concatenate([ud.ravel(), chid])
    a = np.linalg.solve(M + DT**2 * K, F - K @ (x0 + DT * v0))
    v1 = v0 + DT * a
    return x0 + DT * v1, v1


def test_lumped_masses_are_jaxbelts_and_hand_values(belt):
    m_e = np.array([[1.0], [2.0], [3.0], [4.0], [5.0], [6.0]])
    got = belt.masses(m_e)
    np.testing.assert_allclose(got, np.asarray(nodal_masses(MODEL, m_e)), rtol=1e-15)
    # node column i, either row: a quarter of elements i-1 and i, on both DOFs
    np.testing.assert_allclose(got[:, 0], 0.25 * np.array([7.0, 3.0, 5.0, 7.0, 9.0, 11.0]))
    assert got.sum() == pytest.approx(2 * m_e.sum())  # each element's mass shared by its 4 nodes, on 2 DOFs


def test_roller_kinematics_lag_on_the_lateral_position(belt):
    u = _state(1)[0]
    np.testing.assert_allclose(belt.R(u), np.asarray(roller_R(MODEL, u)), rtol=1e-14, atol=1e-16)
    np.testing.assert_array_equal(belt.R(np.zeros((N, B))), R0)
    lever = np.zeros((N, B))
    lever[:, 0::2] = u[:, 1::2]  # the u rows' lever is the node's v
    np.testing.assert_allclose(belt.R(u), R0 + MODEL.R_dz * lever[:, :, None], rtol=1e-15)


def test_stiffness_product_and_step_matrix_are_jaxbelts(belt):
    state = _state(2)
    R, K, M, _ = (np.asarray(a) for a in _jaxbelt_pieces(*state))
    A = belt.matrices(state[4], R).toarray()
    np.testing.assert_allclose(A, M + DT**2 * K, rtol=1e-13, atol=1e-15 * np.abs(A).max())
    x = np.random.default_rng(3).standard_normal(N * B + Q)
    kb, kr = belt.K_apply(R, x[:N * B].reshape(N, B), x[N * B:])
    np.testing.assert_allclose(np.concatenate([kb.ravel(), kr]), K @ x, rtol=1e-12, atol=1e-12)


def test_the_equilibrated_factor_solves_the_unscaled_system(belt):
    state = _state(3)
    A = belt.matrices(state[4], belt.R(state[0]))
    b = np.random.default_rng(4).standard_normal(A.shape[0])
    scale, lu = belt.equilibrated(A)
    np.testing.assert_allclose(scale, 1.0 / np.abs(A.toarray()).max(axis=1), rtol=1e-15)
    np.testing.assert_allclose(lu.solve(scale * b), np.linalg.solve(A.toarray(), b), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("forward", [True, False])
def test_transport_is_jaxbelts_shift_rule(belt, forward):
    u, ud, chi, chid, m_e = _state(5, forward)
    got = belt.transport(u, ud, chi, chid, m_e)
    want = [np.asarray(a) for a in _jaxbelt_transport(u, ud, chi, m_e)]
    for g, w in zip((got[0], got[1], got[2], got[4]), want):
        np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-18)
    np.testing.assert_array_equal(got[3], chid)
    assert got[2][2] == 0.0  # the rotation angle is reset after the step
    assert got[4].sum() == pytest.approx(m_e.sum(), rel=1e-14)  # mass conserved


@pytest.mark.parametrize("seed,forward", [(6, True), (7, False)])
def test_one_step_is_the_dense_backward_euler_step_then_the_transport(belt, seed, forward):
    state = _state(seed, forward)
    x1, v1 = _dense_step(state)
    u1, ud1, chi1, chid1 = x1[:N * B].reshape(N, B), v1[:N * B].reshape(N, B), x1[N * B:], v1[N * B:]
    want = [np.asarray(a) for a in _jaxbelt_transport(u1, ud1, chi1, state[4])]
    got = belt.step(*state)
    for g, w in zip((got[0], got[1], got[2], got[4]), want):
        np.testing.assert_allclose(g, w, rtol=1e-9, atol=1e-12 * np.abs(w).max())
    np.testing.assert_allclose(got[3], chid1, rtol=1e-9, atol=1e-12)
    assert got[3][1] != state[3][1]  # the free roller DOF moved: the step is not trivially the input


def test_a_kept_factor_reproduces_the_step_it_was_taken_at(belt):
    state = _state(8)
    kept = belt.kept_factor(state[0], state[4], "MMD_AT_PLUS_A")
    for g, w in zip(belt.step(*state, kept=kept), belt.step(*state, permc_spec="MMD_AT_PLUS_A")):
        np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-18)
    later = belt.step(*state)
    moved = belt.step(*later, kept=kept)  # another state, the first step's matrix: not the exact step
    assert not np.allclose(moved[0], belt.step(*later)[0], rtol=1e-12, atol=0)


def test_dae_apply_agrees_with_the_stiffness_product(belt):
    """The matrix-free product the jaxbelt step uses is the SciPy reference's ``K`` too."""
    state = _state(9)
    R = belt.R(state[0])
    xb, xr = state[0] + DT * state[1], state[2] + DT * state[3]
    (kb, kr), _ = jax.jit(lambda m_e, R, xb, xr: dae_apply(MODEL, m_e, R, xb, xr))(state[4], R, xb, xr)
    want_b, want_r = belt.K_apply(R, xb, xr)
    np.testing.assert_allclose(np.asarray(kb), want_b, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.asarray(kr), want_r, rtol=1e-12, atol=1e-15)
