"""Elimination of the algebraic variables (static condensation, eq. 3.47–3.50).

With ``x = [x_f; x_e]`` (dynamic; algebraic) the algebraic rows ``K_ee x_e + K_ef x_f = F_e``
give ``x_e = g + P x_f`` with ``P = -K_ee⁻¹ K_ef``, ``g = K_ee⁻¹ F_e``. Substituting into the
dynamic rows yields the ODE for the dynamic unknowns only (eq. 3.50)

$$ \\hat M ẍ_f + \\hat K x_f = \\hat F,\\quad \\hat M = M_{ff} + M_{fe} P,\\quad
   \\hat K = K_{ff} + K_{fe} P,\\quad \\hat F = F_f - K_{fe} g - M_{fe} ẍ_e^0 ,$$

where ``ẍ_e^0`` is the discrete (Backward-Euler) counterpart of ``K_ee⁻¹ F̈_e`` in eq. 3.50:
the acceleration the algebraic unknowns need to reach ``g + P x_f`` from their previous
state. Integrated with Backward Euler this reproduces the direct integrator to round-off;
it is the form that intrusive model order reduction (POD-Galerkin) projects.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from ..assembly import dae_matrices, dae_rhs, roller_R
from ..linalg import join, split
from ._base import AbstractIntegrator


def eliminated_system(model, state, dt, dyn_idx=None, alg_idx=None):
    """The condensed ODE at the current step of size ``dt``: ``(M̂, K̂, F̂, P, g, p)`` with
    ``p = x + Δt ẋ``; the partition defaults to ``model.partition``."""
    if dyn_idx is None:
        dyn_idx, alg_idx = model.partition
    R = roller_R(model, state.u)
    K, M = dae_matrices(model, state.m_e, R)
    Kd, Md = K.to_dense(), M.to_dense()
    F = join(*dae_rhs(model, state.u, state.chi, dt, R))
    f, e = jnp.asarray(dyn_idx), jnp.asarray(alg_idx)
    p = join(state.u, state.chi) + dt * join(state.u_dot, state.chi_dot)
    Kee, Kef, Kfe, Kff = Kd[e][:, e], Kd[e][:, f], Kd[f][:, e], Kd[f][:, f]
    Mfe, Mff = Md[f][:, e], Md[f][:, f]
    P = -jnp.linalg.solve(Kee, Kef)
    g = jnp.linalg.solve(Kee, F[e])
    a_e0 = (g + P @ p[f] - p[e]) / dt**2
    M_hat = Mff + Mfe @ P
    K_hat = Kff + Kfe @ P
    F_hat = F[f] - Kfe @ g - Mfe @ a_e0
    return M_hat, K_hat, F_hat, P, g, p


def recover_state(state, dt, x_f, v_f, P, g, dyn_idx, alg_idx):
    """The full state after a step on the dynamic unknowns: ``x_e = g + P x_f`` exactly, algebraic
    velocities by Backward Euler, written back into ``state`` (shared by every integrator that
    works on the eliminated ODE)."""
    f, e = jnp.asarray(dyn_idx), jnp.asarray(alg_idx)
    x0, v0 = join(state.u, state.chi), join(state.u_dot, state.chi_dot)
    x_e = g + P @ x_f
    x = jnp.zeros_like(x0).at[f].set(x_f).at[e].set(x_e)
    v = jnp.zeros_like(v0).at[f].set(v_f).at[e].set((x_e - x0[e]) / dt)
    n, b = state.u.shape
    (u, chi), (ud, chid) = split(x, n, b), split(v, n, b)
    return eqx.tree_at(lambda s: (s.u, s.u_dot, s.chi, s.chi_dot), state, (u, ud, chi, chid))


class EliminatedBackwardEuler(AbstractIntegrator):
    """Backward Euler on the condensed ODE (the partition is the model's static structure)."""

    def step(self, model, state, dt, run_data=None):
        dyn_idx, alg_idx = model.partition
        M_hat, K_hat, F_hat, P, g, p = eliminated_system(model, state, dt, dyn_idx, alg_idx)
        f = jnp.asarray(dyn_idx)
        a_f = jnp.linalg.solve(M_hat + dt**2 * K_hat, F_hat - K_hat @ p[f])
        v_f = join(state.u_dot, state.chi_dot)[f] + dt * a_f
        x_f = join(state.u, state.chi)[f] + dt * v_f
        return recover_state(state, dt, x_f, v_f, P, g, dyn_idx, alg_idx)
