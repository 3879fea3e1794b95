"""The belt model: a frozen pytree of the physical and discretised system, nothing else.

:func:`jaxbelt.build_model` makes one from a scene. Array fields are pytree leaves, so
``jax.grad`` and ``jax.vmap`` reach material data and the misalignment ``chi_static``; only
true structure (the kind, the roller names and DOFs, which unknowns are algebraic, which
columns touch rollers) is static. How to integrate and what to record are not here: they are
arguments of :func:`jaxbelt.simulate`, so a new time step or misalignment is no new compile.

Unknowns (model specification §2, §4): ``x = [belt DOFs column by column (n_xi, b); roller DOFs (q,)]``
with ``b = 1`` (1D: ``u``) and per roller ``(d_x, α_z)`` in 1D, so ``N = n_xi + 2p``.
*Algebraic* unknowns are the belt DOFs on roller arcs (no-slip constraint rows) and the
prescribed roller DOFs (trivial rows); the others (free-belt nodes, force/torque-loaded
roller DOFs such as an idle roller's ``α_z``) are *dynamic*.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import numpy as np

from .control import SteeringLoops


class BeltModel(eqx.Module):
    """Compiled scene. Shapes: ``n = n_xi`` node columns, ``b`` DOFs per column, ``q`` roller DOFs."""

    x: jax.Array  # (n,) node positions along the path, m
    ell: jax.Array  # (n,) element-column lengths, m
    K_diag: jax.Array  # (n, b, b) free-belt stiffness blocks
    K_lower: jax.Array
    K_upper: jax.Array
    f0: jax.Array  # (n, b) internal force of the pre-tension on free elements, N
    R: jax.Array  # (n, b, q) roller kinematics R_r at the reference lever arm (zero on free nodes)
    R_dz: jax.Array  # (n, b, q) d R_r / d(lever arm) on u-rows (2D weak nonlinearity; 0 in 1D)
    is_constraint: jax.Array  # (n, b) bool: row is a no-slip constraint
    node_roller: jax.Array  # (n,) roller of a node column, -1 on free spans
    node_theta: jax.Array  # (n,) wrap angle of roller columns
    node_radius: jax.Array  # (n,) radius of the roller under a column (0 on free spans)
    node_sense: jax.Array  # (n,) wrap sense s of that roller
    z0: jax.Array  # (n_eta,) lateral node positions, m
    m_e0: jax.Array  # (n,) 1D / (n, n_eta-1) 2D initial element masses, kg
    M_roller: jax.Array  # (q,) roller inertia (m or I)
    dynamic: jax.Array  # (q,) bool: force/torque-loaded roller DOF
    chi_static: jax.Array  # (q,) prescribed values: translations (m), tilts (rad); 0 for α_z
    omega: jax.Array  # (q,) prescribed rate of α_z (drive rollers), rad/s
    is_az: jax.Array  # (q,) bool: rotation about the roller axis (reset by the transport step)
    Q_ext: jax.Array  # (q,) external force/torque on dynamic roller DOFs
    tracer_col: jax.Array  # (n_tr,) element column of each tracer
    tracer_xi: jax.Array  # (n_tr,) local coordinate in [0, 1)
    tracer_row: jax.Array  # (n_tr,) element row (2D; 0 in 1D)
    tracer_eta: jax.Array  # (n_tr,) local lateral coordinate in [0, 1]
    roller_half_width: jax.Array  # (p,) half of each roller's face width (along its axis), m

    kind: str = eqx.field(static=True)
    roller_names: tuple = eqx.field(static=True)
    dofs: tuple = eqx.field(static=True)
    lateral_transport: bool = eqx.field(static=True, default=False)
    contact_columns: tuple | None = eqx.field(static=True, default=None)  # node columns on rollers (None: unknown)
    contact_rollers: tuple | None = eqx.field(static=True, default=None)  # the roller of each of them
    algebraic_index: tuple | None = eqx.field(static=True, default=None)  # flat unknowns with algebraic rows
    control: SteeringLoops | None = None  # steering loops ([[control]]; 2D with lateral transport)

    @property
    def n_eta(self) -> int:
        return self.z0.shape[0]

    @property
    def n_xi(self) -> int:
        return self.x.shape[0]

    @property
    def block(self) -> int:
        return self.R.shape[1]

    @property
    def coupling_band(self) -> int:
        """How far from its diagonal the coupling of one node column to the next reaches in the
        step matrix (the ``L_i``, ``U_i`` blocks): a node couples only to its neighbours across
        the belt, so ``2 p - 1`` for ``p`` unknowns per node — 3 in 2D, 0 in 1D (``b = 1``)."""
        return 2 * 2 - 1 if self.kind == "2d" else 0

    @property
    def n_rollers(self) -> int:
        return len(self.roller_names)

    @property
    def n_roller_dofs(self) -> int:
        return self.R.shape[2]

    @property
    def n_unknowns(self) -> int:
        return self.n_xi * self.block + self.n_roller_dofs

    @property
    def n_algebraic(self) -> int:
        return len(self.partition[1])

    @property
    def partition(self) -> tuple[tuple, tuple]:
        """Static index tuples ``(dynamic, algebraic)`` into the flat unknown vector
        ``[belt; rollers]``: algebraic are the no-slip rows and the prescribed roller DOFs."""
        if self.algebraic_index is None:
            alg = np.concatenate([np.asarray(self.is_constraint).reshape(-1), ~np.asarray(self.dynamic)])
            algebraic = tuple(int(i) for i in np.flatnonzero(alg))
        else:
            algebraic = self.algebraic_index
        rest = sorted(set(range(self.n_unknowns)) - set(algebraic))
        return tuple(rest), tuple(algebraic)

    @property
    def n_tracers(self) -> int:
        return self.tracer_col.shape[0]

    def replace(self, **changes) -> "BeltModel":
        """Copy with fields replaced (arrays, e.g. ``chi_static``, or static structure)."""
        return dataclasses.replace(self, **changes)
