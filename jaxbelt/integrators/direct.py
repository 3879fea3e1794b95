"""Direct Backward Euler on the DAE (eq. 3.54, 7.1) — the default integrator."""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax

from ..assembly import dae_apply, dae_rhs, free_belt_stencil, roller_R
from ._base import AbstractIntegrator
from .linear import AbstractLinearSolver, KeptInterior, StepOperator


class _DirectRunData(eqx.Module):
    stencil: jax.Array | None
    linear: Any


class DirectBackwardEuler(AbstractIntegrator):
    """Solve ``(M + Δt² K) ẍ = F - K (x + Δt ẋ)``, then ``ẋ += Δt ẍ``, ``x += Δt ẋ``.

    ``linear_solver``: one of :mod:`jaxbelt.integrators.linear` (default :class:`KeptInterior`,
    the exact structured solve with the interior's factors kept for the run). Products with the
    free-belt stiffness use the nine-point stencil in 2D (:func:`jaxbelt.assembly.free_belt_stencil`,
    gathered once per run by :meth:`init`).
    """

    linear_solver: AbstractLinearSolver = KeptInterior()

    def __check_init__(self):
        if not isinstance(self.linear_solver, AbstractLinearSolver):
            raise TypeError(f"linear_solver = {self.linear_solver!r}: a linear solver object (KeptInterior(), "
                            "Structured(), CyclicReduction(), Reuse(), Dense()); jaxbelt.make_solver takes names")

    def init(self, model, state, dt):
        return _DirectRunData(free_belt_stencil(model), self.linear_solver.reference(model, state, dt, self.transport))

    def step(self, model, state, dt, run_data):
        on_rollers = self.linear_solver.uses_roller_columns(run_data.linear)
        R = roller_R(model, state.u, on_rollers=on_rollers)
        F_b, F_r = dae_rhs(model, state.u, state.chi, dt, R)
        (Kp_b, Kp_r), _ = dae_apply(model, state.m_e, R, state.u + dt * state.u_dot, state.chi + dt * state.chi_dot,
                                    run_data.stencil)
        operator = StepOperator(model, state.m_e, R, dt, run_data.stencil)
        a_b, a_r = self.linear_solver.solve(operator, F_b - Kp_b, F_r - Kp_r, run_data.linear)
        ud, chid = state.u_dot + dt * a_b, state.chi_dot + dt * a_r
        return eqx.tree_at(
            lambda s: (s.u, s.u_dot, s.chi, s.chi_dot), state,
            (state.u + dt * ud, ud, state.chi + dt * chid, chid),
        )
