"""Direct Backward Euler on the DAE (eq. 3.54, 7.1) — the default integrator."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from ..assembly import (dae_apply, dae_rhs, free_belt_stencil, nodal_masses, roller_R, roller_stiffness_rows,
                        step_matrix)
from ..linalg import BorderedBlockCyclic, bordered_solve, dense_solve
from ..linalg.bordered import (BorderedFactorisation, factor_solve, factor_solve_transposed, factorise,
                               refactorise_border, scaled_schur, solve_with_adjoint, with_chained_interior)
from ._base import AbstractIntegrator


class DirectBackwardEuler(AbstractIntegrator):
    """Solve ``(M + Δt² K) ẍ = F - K (x + Δt ẋ)``, then ``ẋ += Δt ẍ``, ``x += Δt ẋ``.

    ``linear_solver = "structured"`` uses the exact bordered block-cyclic solve
    (:func:`jaxbelt.linalg.bordered_solve`), ``"dense"`` the dense reference. Derivatives of the
    structured solve do not go through its factorisation: it carries its own adjoint, a
    transposed solve with the step's factors (:func:`jaxbelt.linalg.bordered.solve_with_adjoint`),
    and the matrix derivative comes from the structured mat-vec; the dense reference is
    differentiated by JAX's rules for ``jnp.linalg.solve``.

    **Kept interior** (``reference``, set by :meth:`prepare`, which the time loop calls once per
    run before its scan). What changes in ``M + Δt² K`` from one step to the next? The free-belt
    stiffness and the no-slip rows' pattern never do; the lumped masses do not under the
    ``"shift"`` transport rule (its flux is ``s`` times the line density, so every element keeps
    ``ρAℓ`` to round-off: :mod:`jaxbelt.transport`); what does is the lever arm ``z + v`` of the
    roller tilts (§4.2), which enters only the roller columns of the tilt DOFs (``C``), the roller
    rows (``D``) and nothing in the belt's interior blocks. So with the shift rule the interior's
    block factorisation — 97 % of a factorisation — is computed once per run from the model
    itself, and each step recomputes exactly the part of the factors that its matrix changes:
    ``T⁻¹`` of the ``2p`` tilt columns, the roller rows of tilts that are dynamic DOFs, and the
    Schur complement in those columns and rows (:func:`jaxbelt.linalg.bordered.refactorise_border`). That is the exact factorisation of
    the current step's matrix, not an approximation (``tests/test_integrators.py`` compares it
    with a full factorisation every step). The kept factors come from the model the run is
    given (under ``vmap`` over misalignments they are shared, since misalignments change neither
    stiffness nor masses); with the ``"source"`` rule, whose masses move between elements, and
    wherever ``solve_step`` is called without :meth:`prepare`, every step is factored in full
    (as with ``keep_interior=False``, kept for comparisons: ``jaxbelt bench`` times both).
    """

    linear_solver: str = eqx.field(static=True, default="structured")
    interior: str | None = eqx.field(static=True, default=None)  # "thomas" | "cyclic-reduction" | None: by backend
    reference: _KeptInterior | None = None
    lever_columns: tuple | None = eqx.field(static=True, default=None)  # tilt columns of R; None: from the DOFs
    lever_rows: tuple | None = eqx.field(static=True, default=None)  # those of them that are dynamic; None: all
    keep_interior: bool = eqx.field(static=True, default=True)  # False: factor every step in full

    @classmethod
    def for_model(cls, model, linear_solver: str = "structured", interior: str | None = None,
                  keep_interior: bool = True):
        """The integrator for ``model``, with the static facts :meth:`prepare` needs: which roller
        columns carry a lever arm and which of them are dynamic DOFs (whose roller rows then move
        with it too). Read from a concrete model; under tracing, every tilt is taken as dynamic
        (the same result at a little more work)."""
        cols = _lever_columns(model)
        try:
            dyn = np.asarray(model.dynamic)
            rows = tuple(c for c in cols if dyn[c])
        except (jax.errors.TracerArrayConversionError, jax.errors.ConcretizationTypeError):
            rows = cols
        return cls(linear_solver, interior, None, cols, rows, keep_interior)

    def prepare(self, model) -> "DirectBackwardEuler":
        """This integrator with the run's kept interior factors (class docstring), where they apply."""
        if (self.linear_solver != "structured" or not self.keep_interior or self.reference is not None
                or model.transport != "shift" or model.n_xi < 3):
            return self
        cols = _lever_columns(model) if self.lever_columns is None else self.lever_columns
        rows = cols if self.lever_rows is None else self.lever_rows
        kept = _kept_interior(model, self.interior)  # the interior along its chains
        kept = _KeptInterior(*lax.stop_gradient((kept.A, kept.F, kept.S)), free_belt_stencil(model))  # the
        # stencil serves the products, which carry the derivatives; the factors are only a solver
        return DirectBackwardEuler(self.linear_solver, self.interior, kept, cols, rows, True)

    def solve_step(self, model, state):
        dt = model.dt
        kept = self.linear_solver == "structured" and self.reference is not None
        R = roller_R(model, state.u, on_rollers=kept)  # kept interior: the roller columns only
        F_b, F_r = dae_rhs(model, state.u, state.chi, R)
        p_b, p_r = state.u + dt * state.u_dot, state.chi + dt * state.chi_dot
        stencil = None if self.reference is None else self.reference.stencil
        (Kp_b, Kp_r), _ = dae_apply(model, state.m_e, R, p_b, p_r, stencil)
        if kept:
            a_b, a_r = self._kept_interior_solve(model, state, R, F_b - Kp_b, F_r - Kp_r)
        else:
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

    def _kept_interior_solve(self, model, state, R, r_b, r_r):
        """The exact solve with the kept interior: the step's matrix differs from the reference in
        the lever-arm columns of ``C`` and, for dynamic tilts, the rows of ``D`` only."""
        dt, ref = model.dt, self.reference
        cols, rows = self.lever_columns, self.lever_rows
        con = model.is_constraint[:, :, None]
        C, D = ref.A.C, ref.A.D

        def full(Rk):  # columns of R in the full (n, b, k) form
            if Rk.shape[0] == model.n_xi:
                return Rk
            on = np.asarray(model.contact_columns)
            return jnp.zeros((model.n_xi,) + Rk.shape[1:], Rk.dtype).at[on].set(Rk, unique_indices=True)

        if cols:
            C = C.at[:, :, jnp.asarray(cols)].set(jnp.where(con, -dt**2 * full(R[:, :, jnp.asarray(cols)]), 0.0))
        if rows:
            Rr = full(R[:, :, jnp.asarray(rows)])
            m = nodal_masses(model, state.m_e)
            Dr = dt**2 * roller_stiffness_rows(Rr, model.K_diag, model.K_lower, model.K_upper) \
                + jnp.swapaxes(Rr, 1, 2) * m[:, None, :]
            D = D.at[:, jnp.asarray(rows), :].set(jnp.where(model.dynamic[jnp.asarray(rows)][None, :, None], Dr, 0.0))
        A = eqx.tree_at(lambda a: (a.C, a.D), ref.A, (C, D))
        F = refactorise_border(lax.stop_gradient(A), ref.F, ref.S, cols, rows)

        def A_matvec(x_b, x_r):  # the current (M + Δt² K) x, matrix-free: carries the derivatives
            (k_b, k_r), (m_b, m_r) = dae_apply(model, state.m_e, R, x_b, x_r, ref.stencil)
            return m_b + dt**2 * k_b, m_r + dt**2 * k_r

        return solve_with_adjoint(A_matvec, r_b, r_r, lambda _, rb, rr: factor_solve(F, rb, rr),
                                  lambda _, rb, rr: factor_solve_transposed(F, rb, rr))


class _KeptInterior(eqx.Module):
    """The reference step matrix ``A`` (model masses, reference lever arms), its factors ``F``,
    its scaled Schur complement ``S`` and the free-belt stencil (2D, else ``None``)."""

    A: BorderedBlockCyclic
    F: BorderedFactorisation
    S: jax.Array
    stencil: jax.Array | None


def _lever_columns(model) -> tuple:
    """Roller unknowns whose column of ``R`` has a lever arm (the tilts α_x, α_y in 2D)."""
    if model.kind != "2d":
        return ()
    d = len(model.dofs)
    return tuple(j * d + model.dofs.index(a) for j in range(model.n_rollers) for a in ("ax", "ay") if a in model.dofs)


@eqx.filter_jit
def _kept_interior(model, method=None) -> _KeptInterior:
    """Factors of ``M + Δt² K`` at the model's masses and reference lever arms (one compiled
    program: op by op the factorisation is seconds of dispatch)."""
    A = step_matrix(model, model.m_e0, model.R, model.dt)
    F = factorise(A, method)
    return _KeptInterior(A, with_chained_interior(F, model.contact_columns), scaled_schur(A, F), None)
