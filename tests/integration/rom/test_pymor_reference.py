"""POD and POD-Galerkin against pyMOR (an independent MOR library, test-only dependency) on the 1D
model: the same snapshots give the same singular values and basis, and jaxbelt's reduced
operators (assembled by Jacobian-vector products along the basis, ``jaxbelt.rom.pod_step``) equal
pyMOR's Galerkin projection of the same full-order maps, to round-off."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

pytest.importorskip("pymor")
from pymor.algorithms.pod import pod  # noqa: E402
from pymor.algorithms.projection import project  # noqa: E402
from pymor.operators.numpy import NumpyMatrixOperator  # noqa: E402
from pymor.vectorarrays.numpy import NumpyVectorSpace  # noqa: E402

import jaxbelt as jb  # noqa: E402
from helpers import load  # noqa: E402
from jaxbelt.rom import collect_first_order, fit_reduced_pod, parameters, pod_basis, state_to_z  # noqa: E402
from jaxbelt.rom.pod_step import solve_map  # noqa: E402

R = 12


@pytest.fixture(scope="module")
def setup():
    m, opts = load("two-roller-1d-train1")
    _, Zp, Zq = collect_first_order(m, jb.RunOptions(jb.make_solver(), 150, opts.dt))  # the training run of test_rom_dmdc / test_rom_error_estimate
    Z = np.asarray(jnp.concatenate([Zp, Zq], axis=1))
    return m, opts.dt, Z


def _align(V, W):
    """``W`` with each column's sign matched to ``V`` (SVD bases are unique up to sign)."""
    return W * np.sign(np.sum(V * W, axis=0))[None, :]


def test_singular_values_and_basis_equal_pymor_pod(setup):
    m, _, Z = setup
    V, s = pod_basis(jnp.asarray(Z), n_modes=R)
    space = NumpyVectorSpace(Z.shape[0])
    modes, svals = pod(space.from_numpy(Z), modes=R, rtol=0, atol=0, l2_err=0, method="qr_svd")
    assert np.allclose(np.asarray(s)[:R], svals, rtol=1e-10, atol=0)
    W = _align(np.asarray(V), modes.to_numpy())
    assert np.abs(W - np.asarray(V)).max() < 1e-8


def test_reduced_operators_equal_pymor_galerkin_projection(setup):
    m, dt, Z = setup
    rom = fit_reduced_pod(m, jnp.asarray(Z), dt, n_modes=R)
    V = np.asarray(rom.basis)
    solve = solve_map(m, dt, jb.make_solver("direct"))
    z_ref, mu = state_to_z(m, jb.initial_state(m), dt), parameters(m)
    # jit-compiled: one program each instead of a few hundred op-by-op compilations
    S = np.asarray(jax.jit(jax.jacfwd(lambda z: solve(z, mu)))(z_ref))  # dense (2N, 2N) Jacobian of the solve
    T = np.asarray(jax.jit(jax.jacfwd(lambda p: solve(z_ref, p)))(mu))  # (2N, 2q): the configuration inputs
    space = NumpyVectorSpace(V.shape[0])
    basis = space.from_numpy(V)
    A_pymor = project(NumpyMatrixOperator(S), basis, basis).matrix
    B_pymor = project(NumpyMatrixOperator(T), basis, None).matrix
    scale = np.abs(A_pymor).max()
    assert np.abs(np.asarray(rom.A) - A_pymor).max() < 1e-10 * scale
    assert np.abs(np.asarray(rom.B) - B_pymor).max() < 1e-10 * max(np.abs(B_pymor).max(), 1e-300)
