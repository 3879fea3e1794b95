"""Direct Backward Euler with a frozen factorisation and iterative refinement.

The matrix ``M + Δt² K`` changes very little from step to step: with the shift transport the
masses of a uniform belt do not change at all, and only the lever arms of the roller tilts move
with ``v`` (§4.2). So the structured factorisation of the first step is kept and each step
solves the *current* system by iterative refinement preconditioned with it,

$$ x_{k+1} = x_k + F_0^{-1} (r - A x_k), $$

each iteration costing one structured mat-vec and one pair of block triangular sweeps. With
``refine`` iterations the result converges to the exact solve; its error against the exact mode
is measured in ``benchmarks/solver_2d.py`` and ``tests/test_reuse.py``.
"""

from __future__ import annotations

import equinox as eqx

from ..assembly import dae_apply, dae_matrices, dae_rhs, roller_R
from ..linalg.bordered import BorderedFactorisation, factor_solve, factorise
from ..state import initial_state
from ._base import AbstractIntegrator


class ReusedFactorisationBackwardEuler(AbstractIntegrator):
    """Direct Backward Euler whose linear solve reuses ``factors`` (build with :meth:`for_model`)."""

    factors: BorderedFactorisation
    refine: int = eqx.field(static=True, default=2)

    @classmethod
    def for_model(cls, model, refine: int = 2, state=None) -> "ReusedFactorisationBackwardEuler":
        state = initial_state(model) if state is None else state
        R = roller_R(model, state.u)
        K, M = dae_matrices(model, state.m_e, R)
        return cls(factorise(M + K.scale(model.dt**2)), refine)

    def solve_step(self, model, state):
        dt = model.dt
        R = roller_R(model, state.u)

        def A_matvec(x_b, x_r):  # (M + Δt² K) x, matrix-free
            (k_b, k_r), (m_b, m_r) = dae_apply(model, state.m_e, R, x_b, x_r)
            return m_b + dt**2 * k_b, m_r + dt**2 * k_r

        F_b, F_r = dae_rhs(model, state.u, state.chi, R)
        (Kp_b, Kp_r), _ = dae_apply(model, state.m_e, R, state.u + dt * state.u_dot, state.chi + dt * state.chi_dot)
        r_b, r_r = F_b - Kp_b, F_r - Kp_r
        a_b, a_r = factor_solve(self.factors, r_b, r_r)
        for _ in range(self.refine):
            y_b, y_r = A_matvec(a_b, a_r)
            d_b, d_r = factor_solve(self.factors, r_b - y_b, r_r - y_r)
            a_b, a_r = a_b + d_b, a_r + d_r
        ud, chid = state.u_dot + dt * a_b, state.chi_dot + dt * a_r
        return eqx.tree_at(
            lambda s: (s.u, s.u_dot, s.chi, s.chi_dot), state,
            (state.u + dt * ud, ud, state.chi + dt * chid, chid),
        )
