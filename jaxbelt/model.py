"""The compiled belt model: a frozen, jit-friendly pytree holding only what a scene needs.

:func:`compile_scene` turns a validated :class:`~jaxbelt.scene.Scene` into a
:class:`BeltModel`. Array fields are pytree leaves (so ``jax.grad``/``vmap`` reach e.g. the
misalignment ``chi_static``); sizes and settings are static fields.

Unknowns (MODEL.md §2, §4): ``x = [belt DOFs column by column (n_xi, b); roller DOFs (q,)]``
with ``b = 1`` (1D: ``u``) and per roller ``(d_x, α_z)`` in 1D, so ``N = n_xi + 2p``.
*Algebraic* unknowns are the belt DOFs on roller arcs (no-slip constraint rows) and the
prescribed roller DOFs (trivial rows); the others (free-belt nodes, force/torque-loaded
roller DOFs such as an idle roller's ``α_z``) are *dynamic*.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from . import elements, rollers
from .mesh import Mesh, build_mesh
from .scene import Scene, SceneError


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

    dt: float = eqx.field(static=True)
    n_steps: int = eqx.field(static=True)
    kind: str = eqx.field(static=True)
    roller_names: tuple = eqx.field(static=True)
    dofs: tuple = eqx.field(static=True)
    every: int = eqx.field(static=True)
    full_fields: bool = eqx.field(static=True)
    integrator: str = eqx.field(static=True)
    linear_solver: str = eqx.field(static=True)
    transport: str = eqx.field(static=True, default="shift")
    lateral_transport: bool = eqx.field(static=True, default=False)
    contact_columns: tuple | None = eqx.field(static=True, default=None)  # node columns on rollers (None: unknown)

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
        return int(np.sum(np.asarray(self.is_constraint))) + int(np.sum(~np.asarray(self.dynamic)))

    @property
    def n_tracers(self) -> int:
        return self.tracer_col.shape[0]

    def replace(self, **changes) -> "BeltModel":
        """Copy with fields replaced (static settings too, e.g. ``transport="source"``)."""
        return dataclasses.replace(self, **changes)

    def with_misalignment(self, translation=None, rotation=None) -> "BeltModel":
        """Copy with new static roller misalignments (traceable, for ``grad``/``vmap``).

        **Arguments:** ``translation``: (p,) x translations in 1D or (p, 3), m;
        ``rotation``: (p, 3) tilts, rad (2D only). ``None`` keeps the current value.
        """
        chi = self.chi_static.reshape(self.n_rollers, len(self.dofs))
        if translation is not None:
            t = jnp.asarray(translation)
            if t.ndim == 1:
                t = jnp.stack([t, jnp.zeros_like(t), jnp.zeros_like(t)], axis=1)
            for k, ax in enumerate("xyz"):
                if f"d{ax}" in self.dofs:
                    chi = chi.at[:, self.dofs.index(f"d{ax}")].set(t[:, k])
                else:
                    _require_zero(t[:, k], f"translation along {ax}", self.kind)
        if rotation is not None:
            a = jnp.asarray(rotation)
            for k, ax in enumerate("xy"):
                if f"a{ax}" in self.dofs:
                    chi = chi.at[:, self.dofs.index(f"a{ax}")].set(a[:, k])
                else:
                    _require_zero(a[:, k], f"rotation about {ax}", self.kind)
        return eqx.tree_at(lambda m: m.chi_static, self, chi.reshape(-1))


def _require_zero(v, what, kind):
    if not isinstance(v, jax.core.Tracer) and np.any(np.asarray(v) != 0):
        raise ValueError(f"the {kind} model has no {what}")


def compile_scene(scene: Scene, mesh: Mesh | None = None) -> BeltModel:
    """Build the model for a validated scene (1D: MODEL.md §2; 2D: MODEL.md §4)."""
    mesh = build_mesh(scene) if mesh is None else mesh
    return _compile_1d(scene, mesh) if scene.kind == "1d" else _compile_2d(scene, mesh)


def _node_geometry(mesh):
    on = mesh.node_roller >= 0
    j = np.maximum(mesh.node_roller, 0)
    radius = np.where(on, mesh.path.radii[j], 0.0)
    sense = np.where(on, mesh.path.senses[j], 0).astype(float)
    return dict(node_roller=jnp.asarray(mesh.node_roller), node_theta=jnp.asarray(mesh.node_theta),
                node_radius=jnp.asarray(radius), node_sense=jnp.asarray(sense), z0=jnp.asarray(mesh.z),
                contact_columns=tuple(int(i) for i in np.flatnonzero(on)))


def _tracers(mesh):
    col, xi = mesh.tracer_location()
    if mesh.n_eta == 1:
        row, eta = np.zeros_like(col), np.zeros_like(xi)
    else:
        row = np.clip(np.searchsorted(mesh.z, mesh.tracer_z, side="right") - 1, 0, mesh.n_eta - 2)
        eta = (mesh.tracer_z - mesh.z[row]) / (mesh.z[row + 1] - mesh.z[row])
    return dict(tracer_col=jnp.asarray(col), tracer_xi=jnp.asarray(xi), tracer_row=jnp.asarray(row.astype(np.int32)),
                tracer_eta=jnp.asarray(eta))


def _roller_dofs(scene, mesh, dofs):
    """Prescribed values, dynamic mask, drive rates and external loads per roller DOF."""
    p, d = len(scene.rollers), len(dofs)
    dynamic, chi, omega, Q = np.zeros((p, d), bool), np.zeros((p, d)), np.zeros((p, d)), np.zeros((p, d))
    for j, r in enumerate(scene.rollers):
        for k, ax in enumerate("xyz"):
            if f"d{ax}" in dofs:
                c = dofs.index(f"d{ax}")
                chi[j, c], dynamic[j, c], Q[j, c] = r.translation[k], r.force[k] != 0.0, r.force[k]
        for k, ax in enumerate("xy"):
            if f"a{ax}" in dofs:
                c = dofs.index(f"a{ax}")
                chi[j, c], dynamic[j, c], Q[j, c] = r.rotation[k], r.torque[k] != 0.0, r.torque[k]
        c = dofs.index("az")
        dynamic[j, c] = r.role != "drive"
        if r.role == "drive":
            omega[j, c] = mesh.path.senses[j] * r.speed / r.radius  # belt moves forward at V
    is_az = np.zeros((p, d), bool)
    is_az[:, dofs.index("az")] = True
    return dict(dynamic=jnp.asarray(dynamic.reshape(-1)), chi_static=jnp.asarray(chi.reshape(-1)),
                omega=jnp.asarray(omega.reshape(-1)), is_az=jnp.asarray(is_az.reshape(-1)),
                Q_ext=jnp.asarray(Q.reshape(-1)))


def _settings(scene, dofs, kind):
    return dict(dt=scene.time.dt, n_steps=scene.time.n_steps, kind=kind,
                roller_names=tuple(r.name for r in scene.rollers), dofs=dofs, every=scene.output.every,
                full_fields=scene.output.fields == "full", integrator=scene.solver.integrator,
                linear_solver=scene.solver.linear_solver, transport=scene.solver.transport,
                lateral_transport=scene.solver.lateral_transport)


def _compile_2d(scene: Scene, mesh: Mesh) -> BeltModel:
    belt, rl = scene.belt, scene.rollers
    E, nu, t = belt.youngs_modulus, belt.poisson_ratio, belt.thickness
    ell = jnp.asarray(mesh.ell)
    w_rows = jnp.asarray(np.diff(mesh.z))
    free = jnp.asarray(mesh.elem_free, float)
    Kd, Kl, Ku = elements.free_belt_stiffness_2d(ell, w_rows, free, E, nu, t, element=scene.mesh.element)
    eps0 = belt.pre_strain(mesh.length)
    f0 = elements.prestress_force_2d(ell, w_rows, free, E, eps0, t)
    radii = np.array([r.radius for r in rl])
    R0, Rdz = rollers.roller_constraint_rows_2d(mesh.node_roller, mesh.node_theta, mesh.path.senses, radii, mesh.z)
    is_con = np.repeat((mesh.node_roller >= 0)[:, None], 2 * mesh.n_eta, axis=1)
    M_r = rollers.roller_inertia_2d([r.mass for r in rl], radii, [r.width for r in rl])
    model = BeltModel(
        x=jnp.asarray(mesh.x), ell=ell, K_diag=Kd, K_lower=Kl, K_upper=Ku, f0=f0,
        R=jnp.asarray(R0), R_dz=jnp.asarray(Rdz), is_constraint=jnp.asarray(is_con),
        m_e0=elements.quad_masses(ell, w_rows, belt.density, t), M_roller=jnp.asarray(M_r),
        **_node_geometry(mesh), **_roller_dofs(scene, mesh, rollers.DOFS_2D), **_tracers(mesh),
        roller_half_width=jnp.asarray([0.5 * r.width for r in rl]),
        **_settings(scene, rollers.DOFS_2D, "2d"),
    )
    if scene.solver.tension_stiffening:
        from .prestress import with_tension_stiffening

        model = with_tension_stiffening(model, free, E, nu, t, eps0)
    return model


def _compile_1d(scene: Scene, mesh: Mesh) -> BeltModel:
    belt, rl = scene.belt, scene.rollers
    p = len(rl)
    EA = belt.youngs_modulus * belt.area
    rhoA = belt.density * belt.area
    ell = jnp.asarray(mesh.ell)
    free = jnp.asarray(mesh.elem_free, float)
    Kd, Kl, Ku = elements.free_belt_stiffness_1d(ell, free, EA)
    eps0 = belt.pre_strain(mesh.length)  # uniform pre-strain of a belt shorter than its path
    f0 = elements.prestress_force_1d(free, EA, eps0)
    radii = np.array([r.radius for r in rl])
    R = rollers.roller_constraint_rows_1d(mesh.node_roller, mesh.node_theta, mesh.path.senses, radii)
    is_con = (mesh.node_roller >= 0)[:, None]
    return BeltModel(
        x=jnp.asarray(mesh.x), ell=ell, K_diag=Kd, K_lower=Kl, K_upper=Ku, f0=f0,
        R=jnp.asarray(R), R_dz=jnp.zeros(R.shape), is_constraint=jnp.asarray(is_con),
        m_e0=rhoA * ell, M_roller=jnp.asarray(rollers.roller_inertia_1d([r.mass for r in rl], radii)),
        **_node_geometry(mesh), **_roller_dofs(scene, mesh, rollers.DOFS_1D), **_tracers(mesh),
        roller_half_width=jnp.asarray([0.5 * r.width for r in rl]),
        **_settings(scene, rollers.DOFS_1D, "1d"),
    )
