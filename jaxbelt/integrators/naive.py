"""The source's original 'naive' 3N system (eq. 3.43)."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from ..assembly import dae_matrices, dae_rhs, roller_R
from ..linalg import join, split
from ._base import AbstractIntegrator


class NaiveBackwardEuler(AbstractIntegrator):
    """Solve for ``[x; ẋ; ẍ]`` at once:

    $$\\begin{bmatrix} K & 0 & M \\\\ I & -Δt I & 0 \\\\ 0 & I & -Δt I \\end{bmatrix}
    \\begin{bmatrix} x_m \\\\ ẋ_m \\\\ ẍ_m \\end{bmatrix} =
    \\begin{bmatrix} F \\\\ x_{m-1} \\\\ ẋ_{m-1} \\end{bmatrix}$$

    with a dense solve of size 3N, as the source's simulator did. Kept as the reference for
    what the direct formulation saves; it agrees with it to round-off.

    The 3N matrix mixes stiffness (~EA/ℓ), mass and unit rows; unscaled its condition number
    on ``two-roller-1d-train1`` is ~1e13. Rows and then columns are equilibrated by their largest
    entry before the solve (condition ~1e7), which is what makes it agree with the direct
    integrator to round-off.
    """

    def step(self, model, state, dt, run_data=None):
        R = roller_R(model, state.u)
        K, M = dae_matrices(model, state.m_e, R)
        Kd, Md = K.to_dense(), M.to_dense()
        N = Kd.shape[0]
        I, Z = jnp.eye(N), jnp.zeros((N, N))
        A = jnp.block([[Kd, Z, Md], [I, -dt * I, Z], [Z, I, -dt * I]])
        F = join(*dae_rhs(model, state.u, state.chi, dt, R))
        rhs = jnp.concatenate([F, join(state.u, state.chi), join(state.u_dot, state.chi_dot)])
        r = 1.0 / jnp.max(jnp.abs(A), axis=1)
        A = A * r[:, None]
        c = 1.0 / jnp.max(jnp.abs(A), axis=0)
        sol = c * jnp.linalg.solve(A * c[None, :], rhs * r)
        n, b = state.u.shape
        u, chi = split(sol[:N], n, b)
        ud, chid = split(sol[N:2 * N], n, b)
        return eqx.tree_at(lambda s: (s.u, s.u_dot, s.chi, s.chi_dot), state, (u, ud, chi, chid))
