"""Direct Backward Euler on the DAE (eq. 3.54, 7.1) — the default integrator."""

from __future__ import annotations

import equinox as eqx

from ..assembly import dae_apply, dae_rhs, roller_R, step_matrix
from ..linalg import bordered_solve, dense_solve
from ._base import AbstractIntegrator


class DirectBackwardEuler(AbstractIntegrator):
    """Solve ``(M + Δt² K) ẍ = F - K (x + Δt ẋ)``, then ``ẋ += Δt ẍ``, ``x += Δt ẋ``.

    ``linear_solver = "structured"`` uses the exact bordered block-cyclic solve
    (:func:`jaxbelt.linalg.bordered_solve`), ``"dense"`` the dense reference. Derivatives of the
    structured solve do not go through its factorisation: it carries its own adjoint, a
    transposed solve with the step's factors (:func:`jaxbelt.linalg.bordered.solve_with_adjoint`),
    and the matrix derivative comes from the structured mat-vec; the dense reference is
    differentiated by JAX's rules for ``jnp.linalg.solve``.
    """

    linear_solver: str = eqx.field(static=True, default="structured")
    interior: str | None = eqx.field(static=True, default=None)  # "thomas" | "cyclic-reduction" | None: by backend

    def solve_step(self, model, state):
        dt = model.dt
        R = roller_R(model, state.u)
        F_b, F_r = dae_rhs(model, state.u, state.chi, R)
        p_b, p_r = state.u + dt * state.u_dot, state.chi + dt * state.chi_dot
        (Kp_b, Kp_r), _ = dae_apply(model, state.m_e, R, p_b, p_r)
        A = step_matrix(model, state.m_e, R, dt)
        if self.linear_solver == "structured":
            a_b, a_r = bordered_solve(A, F_b - Kp_b, F_r - Kp_r, self.interior)
        else:
            a_b, a_r = dense_solve(A, F_b - Kp_b, F_r - Kp_r)
        ud, chid = state.u_dot + dt * a_b, state.chi_dot + dt * a_r
        return eqx.tree_at(
            lambda s: (s.u, s.u_dot, s.chi, s.chi_dot), state,
            (state.u + dt * ud, ud, state.chi + dt * chid, chid),
        )
