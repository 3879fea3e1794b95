"""Linear solvers for the Backward-Euler step matrix ``A = M + Δt² K`` (eq. 3.54, 7.1).

Each solver has the shape of a lineax solver: :meth:`~AbstractLinearSolver.init` turns the step's
operator into a solver state (factors), :meth:`~AbstractLinearSolver.compute` solves with that
state and :meth:`~AbstractLinearSolver.transpose` gives the state that solves with ``Aᵀ`` (the
adjoint solve of reverse mode). One step runs :meth:`~AbstractLinearSolver.solve`, which wraps
the three in the implicit-function rule (:func:`jaxbelt.linalg.bordered.solve_with_adjoint`):
derivatives never go through a factorisation; forward mode re-solves with the same factors,
reverse mode solves once with their transpose, and the dependence of ``A`` on the parameters
comes from the matrix-free product :meth:`StepOperator.mv`.

Some solvers keep data for a whole run — the kept interior factors, the frozen first-step
factors: :meth:`~AbstractLinearSolver.reference` computes it once, inside the compiled run
(:func:`jaxbelt.simulate` calls it through the integrator's ``init``), from the model, the
start state and the time step; it is passed back to every :meth:`~AbstractLinearSolver.init`.

| solver | per step | exact |
|---|---|---|
| :class:`Structured` | factor the bordered block-cyclic matrix in full (Thomas interior on a CPU) | yes |
| :class:`CyclicReduction` | the same with a cyclic-reduction interior (``log₂ n`` levels) | yes |
| :class:`KeptInterior` | refactor the few roller columns and rows the lever arms change | yes |
| :class:`Reuse` | the first step's factors, ``refine`` steps of iterative refinement | to the refinement |
| :class:`Dense` | dense LU of the assembled matrix (reference; JAX's own derivative rules) | yes |
"""

from __future__ import annotations

import abc
import dataclasses
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from ..assembly import dae_apply, nodal_masses, roller_R, roller_stiffness_rows, step_matrix
from ..linalg import BorderedBlockCyclic, dense_solve, join, split
from ..linalg.border_first import (BorderFirstFactors, border_first, border_first_solve, border_first_solve_transposed,
                                   border_green, replace_border_columns)
from ..linalg.bordered import (BorderedFactorisation, factor_solve, factor_solve_transposed, factorise,
                               refactorise_border, scaled_schur, solve_with_adjoint, with_chained_interior)
from ..model import BeltModel
from ..infra.programs import stored_jit


class StepOperator(eqx.Module):
    """``A = M + Δt² K`` of one step, kept as the data it is made of; a solver takes what it needs.

    **Fields:** ``model``; ``m_e`` element masses of the step (n,) or (n, n_eta - 1), kg; ``R``
    roller kinematics, full (n, b, q) or on the roller columns only (``on_rollers``); ``dt``
    time step, s (a traced scalar); ``stencil`` the 2D free-belt stencil or ``None``.
    """

    model: BeltModel
    m_e: jax.Array
    R: jax.Array
    dt: jax.Array
    stencil: jax.Array | None = None

    def mv(self, x_b, x_r):
        """``A x`` matrix-free: ``(belt (n, b), roller (q,))``."""
        (k_b, k_r), (m_b, m_r) = dae_apply(self.model, self.m_e, self.R, x_b, x_r, self.stencil)
        return m_b + self.dt**2 * k_b, m_r + self.dt**2 * k_r

    def full_R(self):
        """``R`` in its full (n, b, q) form."""
        model, R = self.model, self.R
        if R.shape[0] == model.n_xi:
            return R
        on = np.asarray(model.contact_columns)
        return jnp.zeros((model.n_xi,) + R.shape[1:], R.dtype).at[on].set(R, unique_indices=True)

    def matrix(self) -> BorderedBlockCyclic:
        """``A`` assembled in the bordered block-cyclic format."""
        return step_matrix(self.model, self.m_e, self.full_R(), self.dt)


class AbstractLinearSolver(eqx.Module):
    """Solves ``A a = r`` for the step's acceleration (module docstring)."""

    def reference(self, model: BeltModel, state, dt, transport: str = "shift") -> Any:
        """Data kept for the whole run (``None`` by default), computed once from the model, the
        start ``state``, the time step ``dt`` and the integrator's transport rule."""
        return None

    def uses_roller_columns(self, reference) -> bool:
        """Whether the step's ``R`` may come on the roller columns only (cheaper to form)."""
        return False

    def keeps_model_masses(self, model: BeltModel, transport: str = "shift") -> bool:
        """Whether the kept data assume the model's element masses (``m_e0``) for the whole run, so
        that a start state with other masses would be stepped with the wrong matrix."""
        return False

    @abc.abstractmethod
    def init(self, operator: StepOperator, reference) -> Any:
        """The solver state for ``operator`` (factors; never differentiated)."""

    @abc.abstractmethod
    def compute(self, state, r_b, r_r):
        """``A⁻¹ r`` with ``state``: ``(a_b (n, b), a_r (q,))``."""

    @abc.abstractmethod
    def transpose(self, state) -> Any:
        """The state that solves with ``Aᵀ`` instead."""

    def solve(self, operator: StepOperator, r_b, r_r, reference=None):
        """``A⁻¹ r``, differentiated by the implicit-function rule (module docstring)."""
        state = self.init(operator, reference)
        state_T = self.transpose(state)
        return solve_with_adjoint(operator.mv, r_b, r_r, lambda _, rb, rr: self.compute(state, rb, rr),
                                  lambda _, rb, rr: self.compute(state_T, rb, rr))


class _Factors(eqx.Module):
    """Bordered factors (interior first or border first) and which way they solve."""

    F: BorderedFactorisation | BorderFirstFactors
    transposed: bool = eqx.field(static=True, default=False)


def _solve_with(F, r_b, r_r, transposed: bool = False):
    """``A⁻¹ r`` (``A⁻ᵀ r``) with either kind of bordered factors."""
    if isinstance(F, BorderFirstFactors):
        return (border_first_solve_transposed if transposed else border_first_solve)(F, r_b, r_r)
    return (factor_solve_transposed if transposed else factor_solve)(F, r_b, r_r)


def _factored_compute(state, r_b, r_r):
    """Solve with bordered factors, or densely where the belt was too short to factor
    (:class:`_DenseLU`, see :class:`Structured`)."""
    if isinstance(state, _DenseLU):
        return _dense_compute(state, r_b, r_r)
    return _solve_with(state.F, r_b, r_r, state.transposed)


def _flip(state):
    """The same factors, solving the other way."""
    return dataclasses.replace(state, transposed=not state.transposed)


class Structured(AbstractLinearSolver):
    """The exact structured solve: the bordered block-cyclic matrix (model specification §4) factored in full
    every step, ``O(n b³)`` (:func:`jaxbelt.linalg.bordered.factorise`).

    ``interior``: ``"thomas"``, ``"cyclic-reduction"`` or ``None`` (by backend:
    :func:`jaxbelt.linalg.bordered.default_interior_method`). A belt of fewer than three node
    columns has no interior: it is solved densely."""

    interior: str | None = eqx.field(static=True, default=None)

    def init(self, operator, reference=None):
        if operator.model.n_xi < 3:
            return Dense().init(operator, None)
        return _Factors(factorise(lax.stop_gradient(operator.matrix()), self.interior))

    def compute(self, state, r_b, r_r):
        return _factored_compute(state, r_b, r_r)

    def transpose(self, state):
        return _flip(state)


class CyclicReduction(Structured):
    """:class:`Structured` with the interior factored by block cyclic reduction: ``log₂ n``
    batched levels instead of a sequential chain (what pays on an accelerator)."""

    interior: str | None = eqx.field(static=True, default="cyclic-reduction")


class _Kept(eqx.Module):
    """Run data of :class:`KeptInterior`: the reference matrix (model masses, reference lever
    arms), its factors (border first where ``green`` is not ``None``), its scaled Schur
    complement, and the border rows' Green's functions ``green`` on the roller columns."""

    A: BorderedBlockCyclic
    F: BorderedFactorisation | BorderFirstFactors
    S: jax.Array
    green: jax.Array | None = None


class KeptInterior(AbstractLinearSolver):
    """The exact structured solve with the belt interior's factors kept for the whole run.

    What changes in ``M + Δt² K`` from one step to the next? The free-belt stiffness and the
    no-slip rows' pattern never do; the lumped masses do not under the ``"shift"`` transport
    rule (its flux is ``s`` times the line density, so every element keeps ``ρAℓ`` to
    round-off: :mod:`jaxbelt.transport`); what does is the lever arm ``z + v`` of the roller tilts
    (§4.2), which enters only the roller columns of the tilt DOFs (``C``) and the roller rows of
    the dynamic ones (``D``). So the interior's block factorisation — 97 % of a factorisation —
    is computed once per run (:meth:`reference`) and each step recomputes exactly the part of the
    factors its matrix changes (``border``, below). That is the
    exact factorisation of the current step's matrix, not an approximation. Under ``vmap`` over
    misalignments the kept factors are shared, since misalignments change neither stiffness nor
    masses. Where the transport rule moves masses between elements (``"source"``) every step is
    factored in full, as :class:`Structured`.

    ``border``: how a step's new tilt columns enter the kept factors, both exact.

    * ``"green"`` (default where the tilts are prescribed DOFs): border first
      (:mod:`jaxbelt.linalg.border_first`). The Green's functions of the border rows, ``H T⁻¹``,
      are computed once per run; a step changes only the Schur complement's tilt columns, by a
      small product with them on the roller columns, and each solve is one sweep — the cost of a
      solve with frozen factors.
    * ``"sweep"``: interior first. Each step sweeps its tilt columns through the kept interior
      (:func:`jaxbelt.linalg.bordered.refactorise_border`), a sweep with one right-hand side per
      tilt, and each solve is one sweep and a product. Where a tilt is a dynamic DOF (its roller
      row moves with the lever arm too, which needs ``T⁻¹`` of the columns) ``"green"`` takes this
      path as well.
    """

    interior: str | None = eqx.field(static=True, default=None)
    border: str = eqx.field(static=True, default="green")

    def __check_init__(self):
        if self.border not in ("green", "sweep"):
            raise ValueError(f"KeptInterior(border={self.border!r}): 'green' or 'sweep'")

    def reference(self, model, state, dt, transport="shift"):
        if not self.keeps_model_masses(model, transport):
            return None
        return _kept_interior(model, dt, self.interior, self.border == "green")

    def keeps_model_masses(self, model, transport="shift"):
        return transport == "shift" and model.n_xi >= 3

    def uses_roller_columns(self, reference) -> bool:
        return reference is not None

    def init(self, operator, reference=None):
        if reference is None:
            return Structured(self.interior).init(operator)
        model, dt = operator.model, operator.dt
        cols, rows = lever_columns(model)
        if reference.green is not None:  # border first: the tilt columns on the roller columns only
            on = np.asarray(model.contact_columns, int)
            R = operator.R[on] if operator.R.shape[0] == model.n_xi else operator.R
            C_on = jnp.where(model.is_constraint[on][:, :, None], -dt**2 * R[:, :, jnp.asarray(cols)], 0.0)
            return _Factors(replace_border_columns(reference.F, reference.S, reference.green, reference.A.E, cols,
                                                   lax.stop_gradient(C_on), on))
        con = model.is_constraint[:, :, None]
        C, D = reference.A.C, reference.A.D
        if cols:
            R_cols = StepOperator(model, operator.m_e, operator.R[:, :, jnp.asarray(cols)], dt).full_R()
            C = C.at[:, :, jnp.asarray(cols)].set(jnp.where(con, -dt**2 * R_cols, 0.0))
        if rows:
            Rr = StepOperator(model, operator.m_e, operator.R[:, :, jnp.asarray(rows)], dt).full_R()
            m = nodal_masses(model, operator.m_e)
            Dr = dt**2 * roller_stiffness_rows(Rr, model.K_diag, model.K_lower, model.K_upper) \
                + jnp.swapaxes(Rr, 1, 2) * m[:, None, :]
            D = D.at[:, jnp.asarray(rows), :].set(jnp.where(model.dynamic[jnp.asarray(rows)][None, :, None], Dr, 0.0))
        A = eqx.tree_at(lambda a: (a.C, a.D), reference.A, (C, D))
        return _Factors(refactorise_border(lax.stop_gradient(A), reference.F, reference.S, cols, rows,
                                           roller_column_blocks(model, cols)))

    def compute(self, state, r_b, r_r):
        return _factored_compute(state, r_b, r_r)

    def transpose(self, state):
        return _flip(state)


def roller_column_blocks(model: BeltModel, cols) -> tuple:
    """Per roller unknown in ``cols``, the interior blocks where its column of ``R`` can be
    non-zero: the belt columns on its own roller (column ``i`` is interior block ``i - 1``;
    column 0 belongs to the border). Empty where the model does not know its rollers' columns."""
    if model.contact_rollers is None or model.contact_columns is None:
        return ()
    d = len(model.dofs)
    return tuple(tuple(c - 1 for c, r in zip(model.contact_columns, model.contact_rollers) if r == col // d and c)
                 for col in cols)


def lever_columns(model: BeltModel) -> tuple[tuple, tuple]:
    """Roller unknowns whose column of ``R`` has a lever arm (the tilts ``α_x``, ``α_y`` in 2D),
    and those of them that are dynamic (whose roller rows move with the lever arm too)."""
    if model.kind != "2d":
        return (), ()
    d = len(model.dofs)
    cols = tuple(j * d + model.dofs.index(a) for j in range(model.n_rollers) for a in ("ax", "ay") if a in model.dofs)
    dynamic = set(dynamic_roller_rows(model))
    return cols, tuple(c for c in cols if c in dynamic)


def border_first_possible(model: BeltModel) -> bool:
    """Whether the kept factors are border first (:class:`KeptInterior` ``"green"``): the model
    has tilts with a lever arm (2D), none of them a dynamic DOF, and knows its roller columns."""
    cols, rows = lever_columns(model)
    return model.contact_columns is not None and bool(cols) and not rows


def dynamic_roller_rows(model: BeltModel) -> tuple:
    """The roller unknowns whose rows of ``D`` can be non-zero: the dynamic (force- or
    torque-loaded) roller DOFs; a prescribed DOF's row is its constraint alone."""
    algebraic = set(model.partition[1])
    n_belt = model.n_xi * model.block
    return tuple(c for c in range(model.n_roller_dofs) if n_belt + c not in algebraic)


def contact_blocks(model: BeltModel) -> tuple:
    """The interior blocks (belt column ``i`` is block ``i - 1``) of the belt's roller columns,
    where ``R`` and so the roller columns ``C`` can be non-zero."""
    return tuple(int(c) - 1 for c in model.contact_columns if int(c) != 0)


@stored_jit
def _kept_interior(model, dt, method=None, green: bool = False) -> _Kept:
    """Factors of ``M + Δt² K`` at the model's masses and reference lever arms, the interior along
    its chains of dependent blocks (one compiled program); with ``green`` (static) and where
    :func:`border_first_possible`, border first. Constants of the run: never differentiated (the
    products carry the derivatives)."""
    A = step_matrix(model, model.m_e0, model.R, dt)
    F = factorise(A, method)
    S = scaled_schur(A, F)
    F = with_chained_interior(F, model.contact_columns, model.coupling_band)
    if not (green and border_first_possible(model)):
        return lax.stop_gradient(_Kept(A, F, S))
    blocks = contact_blocks(model)
    Phi = border_green(F)
    Fb = border_first(F, A, dynamic_roller_rows(model), blocks, Phi)
    return lax.stop_gradient(_Kept(A, Fb, S, Phi[:, np.asarray(blocks, int)]))


class _Frozen(eqx.Module):
    """Run data of :class:`Reuse`: the first step's factors and the refinement iterations."""

    F: BorderedFactorisation
    refine: int = eqx.field(static=True)


class _Refined(eqx.Module):
    """Frozen factors, the current operator (a constant of the solve) and the direction."""

    F: BorderedFactorisation
    operator: StepOperator
    refine: int = eqx.field(static=True)
    transposed: bool = eqx.field(static=True, default=False)


class Reuse(AbstractLinearSolver):
    """The first step's factors kept for the run; each step solves the *current* system by
    iterative refinement preconditioned with them,

    $$ x_{k+1} = x_k + F_0^{-1} (r - A x_k), $$

    each iteration one matrix-free product and one pair of block triangular sweeps. The step
    matrix changes very little from step to step: with the shift transport the masses of a uniform
    belt do not change at all and only the lever arms of the roller tilts move with ``v`` (§4.2).
    Derivatives treat the refined solution as the exact ``A⁻¹ r`` (implicit-function rule): the
    adjoint is the same refinement transposed, ``λ_{k+1} = λ_k + F_0^{-T} (x̄ - Aᵀ λ_k)``.

    ``refine``: iterations; ``None`` takes :func:`default_refinement` (0 where the step matrix
    cannot drift, else 2). Its error against the exact solve is measured in the benchmarks.
    """

    refine: int | None = eqx.field(static=True, default=None)

    def reference(self, model, state, dt, transport="shift"):
        return _Frozen(_first_step_factors(model, state, dt), self.iterations(model, transport))

    def uses_roller_columns(self, reference) -> bool:
        return True

    def iterations(self, model, transport: str = "shift") -> int:
        """The refinement iterations used on ``model`` with the ``transport`` rule."""
        return default_refinement(model, transport) if self.refine is None else int(self.refine)

    def init(self, operator, reference):
        return _Refined(reference.F, lax.stop_gradient(operator), reference.refine)

    def compute(self, state, r_b, r_r):
        if state.transposed:
            spec = (jax.ShapeDtypeStruct(r_b.shape, r_b.dtype), jax.ShapeDtypeStruct(r_r.shape, r_r.dtype))
            vecmat = jax.linear_transpose(state.operator.mv, *spec)
            return _refined(lambda *r: _solve_with(state.F, *r, transposed=True), lambda *x: vecmat(x), r_b, r_r,
                            state.refine)
        return _refined(lambda *r: _solve_with(state.F, *r), state.operator.mv, r_b, r_r, state.refine)

    def transpose(self, state):
        return _Refined(state.F, state.operator, state.refine, not state.transposed)


@stored_jit
def _first_step_factors(model, state, dt) -> BorderedFactorisation:
    """The structured factors of ``M + Δt² K`` at ``state``, the interior along its chains
    (:func:`~jaxbelt.linalg.bordered.with_chained_interior`), as one compiled program."""
    A = step_matrix(model, state.m_e, roller_R(model, state.u), dt)
    # the dense coupling: one right-hand side per solve, whose sweeps are paced by the dependent
    # chain's latency more than by their bytes (the banded form is for sweeps of several columns)
    return lax.stop_gradient(with_chained_interior(factorise(A), model.contact_columns))


def default_refinement(model: BeltModel, transport: str = "shift") -> int:
    """Refinement iterations by default: 0 with the shift transport and no lateral transport, else 2.

    There the step matrix changes only through the lever arm of the static lateral deflection and
    the frozen factors alone reproduce the exact solver's tracers to round-off (measured in the
    refinement benchmark). With lateral transport the belt can walk and the lever arms keep
    growing, and with the source's transport rule the element masses change: there the
    refinement stays on."""
    return 0 if transport == "shift" and not model.lateral_transport else 2


def _refined(solve0, matvec, r_b, r_r, refine: int):
    """``refine`` steps of iterative refinement of ``solve0(r)`` against ``matvec``."""
    a_b, a_r = solve0(r_b, r_r)
    for _ in range(refine):
        y_b, y_r = matvec(a_b, a_r)
        d_b, d_r = solve0(r_b - y_b, r_r - y_r)
        a_b, a_r = a_b + d_b, a_r + d_r
    return a_b, a_r


class _DenseLU(eqx.Module):
    """The assembled matrix and which way it solves."""

    A: BorderedBlockCyclic
    transposed: bool = eqx.field(static=True, default=False)


def _dense_compute(state: _DenseLU, r_b, r_r):
    if not state.transposed:
        return dense_solve(state.A, r_b, r_r)
    n, b = r_b.shape
    return split(jnp.linalg.solve(state.A.to_dense().T, join(r_b, r_r)), n, b)


class Dense(AbstractLinearSolver):
    """Reference: ``jnp.linalg.solve`` on the assembled, row-equilibrated matrix, differentiated by
    JAX's own rules (independent of the structured solvers' adjoint)."""

    def init(self, operator, reference=None):
        return _DenseLU(operator.matrix())

    def compute(self, state, r_b, r_r):
        return _dense_compute(state, r_b, r_r)

    def transpose(self, state):
        return _flip(state)

    def solve(self, operator, r_b, r_r, reference=None):
        return dense_solve(operator.matrix(), r_b, r_r)

