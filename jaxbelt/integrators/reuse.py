"""Direct Backward Euler with a frozen factorisation and iterative refinement.

The matrix ``M + Δt² K`` changes very little from step to step: with the shift transport the
masses of a uniform belt do not change at all, and only the lever arms of the roller tilts move
with ``v`` (§4.2). So the structured factorisation of the first step is kept and each step
solves the *current* system by iterative refinement preconditioned with it,

$$ x_{k+1} = x_k + F_0^{-1} (r - A x_k), $$

each iteration costing one structured mat-vec and one pair of block triangular sweeps. With
``refine`` iterations the result converges to the exact solve; its error against the exact mode
is measured in ``benchmarks/refinement.py``, ``benchmarks/solver_2d.py`` and
``tests/test_reuse.py``; the default number is :func:`default_refinement`.

Derivatives treat the refined solution as the exact ``A⁻¹ r`` (implicit-function rule,
:func:`jaxbelt.linalg.bordered.solve_with_adjoint`): the adjoint solve is the same refinement
transposed, ``λ_{k+1} = λ_k + F_0^{-T} (x̄ - Aᵀ λ_k)``, with the frozen factors and the current
matrix's transposed mat-vec; the frozen factors are never differentiated.
"""

from __future__ import annotations

import equinox as eqx
import jax
from jax import lax

from ..assembly import dae_apply, dae_matrices, dae_rhs, free_belt_stencil, roller_R
from ..linalg.bordered import (BorderedFactorisation, factor_solve, factor_solve_transposed, factorise,
                              solve_with_adjoint, with_chained_interior)
from ..state import initial_state
from ._base import AbstractIntegrator


class ReusedFactorisationBackwardEuler(AbstractIntegrator):
    """Direct Backward Euler whose linear solve reuses ``factors`` (build with :meth:`for_model`)."""

    factors: BorderedFactorisation
    refine: int = eqx.field(static=True, default=2)
    stencil: jax.Array | None = None  # the free-belt stencil (2D), set by :meth:`prepare`

    def prepare(self, model) -> "ReusedFactorisationBackwardEuler":
        """With the free-belt product as a nine-point stencil (:func:`jaxbelt.assembly.free_belt_stencil`,
        a sixth of the block product's work), gathered once per run from the model's blocks."""
        if self.stencil is not None or model.kind != "2d":
            return self
        return eqx.tree_at(lambda s: s.stencil, self, free_belt_stencil(model), is_leaf=lambda x: x is None)

    @classmethod
    def for_model(cls, model, refine: int | None = None, state=None) -> "ReusedFactorisationBackwardEuler":
        """Factors of ``model``'s first step, the interior along its chains of dependent blocks
        (:class:`jaxbelt.linalg.thomas.ChainedThomasFactors`). ``refine`` defaults to
        :func:`default_refinement`."""
        refine = default_refinement(model) if refine is None else int(refine)
        state = initial_state(model) if state is None else state
        F = _first_step_factors(model, state)
        return cls(lax.stop_gradient(F), refine)

    def solve_step(self, model, state):
        dt = model.dt
        R = roller_R(model, state.u, on_rollers=True)  # the roller columns only

        def A_matvec(x_b, x_r):  # (M + Δt² K) x, matrix-free
            (k_b, k_r), (m_b, m_r) = dae_apply(model, state.m_e, R, x_b, x_r, self.stencil)
            return m_b + dt**2 * k_b, m_r + dt**2 * k_r

        F_b, F_r = dae_rhs(model, state.u, state.chi, R)
        (Kp_b, Kp_r), _ = dae_apply(model, state.m_e, R, state.u + dt * state.u_dot, state.chi + dt * state.chi_dot,
                                    self.stencil)
        a_b, a_r = solve_with_adjoint(
            A_matvec, F_b - Kp_b, F_r - Kp_r,
            lambda matvec, rb, rr: _refined(lambda *r: factor_solve(self.factors, *r), matvec, rb, rr, self.refine),
            lambda vecmat, rb, rr: _refined(lambda *r: factor_solve_transposed(self.factors, *r), vecmat, rb, rr,
                                            self.refine),
        )
        ud, chid = state.u_dot + dt * a_b, state.chi_dot + dt * a_r
        return eqx.tree_at(
            lambda s: (s.u, s.u_dot, s.chi, s.chi_dot), state,
            (state.u + dt * ud, ud, state.chi + dt * chid, chid),
        )


@eqx.filter_jit
def _first_step_factors(model, state) -> BorderedFactorisation:
    """The structured factors of ``M + Δt² K`` at ``state``, the interior along its chains
    (:func:`~jaxbelt.linalg.bordered.with_chained_interior`), as one compiled program (op by op
    it took ~6 s of dispatch and per-primitive compiles before a run could start; compiled once
    it is kept by the persistent compilation cache)."""
    R = roller_R(model, state.u)
    K, M = dae_matrices(model, state.m_e, R)
    return with_chained_interior(factorise(M + K.scale(model.dt**2)), model.contact_columns)


def default_refinement(model) -> int:
    """Refinement iterations by default: 0 with the shift transport and no lateral transport, else 2.

    Decision, from ``benchmarks/refinement.py`` on ``three-roller-t72`` (5000 steps): the frozen
    factors alone reproduce the exact solver's tracers to 3.3e-13 mm (1, 2, 3 iterations:
    4.9e-13, 4.8e-13, 6.3e-13 mm — round-off all) at 0.94 ms per step against 1.97 ms with 2
    iterations. There the step matrix changes only through the lever arm of the static lateral
    deflection. With lateral transport the belt can walk and the lever arms keep growing, and
    with the source's transport rule the element masses change: there the refinement stays on."""
    return 0 if model.transport == "shift" and not model.lateral_transport else 2


def _refined(solve0, matvec, r_b, r_r, refine: int):
    """``refine`` steps of iterative refinement of ``solve0(r)`` against ``matvec``."""
    a_b, a_r = solve0(r_b, r_r)
    for _ in range(refine):
        y_b, y_r = matvec(a_b, a_r)
        d_b, d_r = solve0(r_b - y_b, r_r - y_r)
        a_b, a_r = a_b + d_b, a_r + d_r
    return a_b, a_r
