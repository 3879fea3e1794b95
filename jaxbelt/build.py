"""Model construction: a validated scene and its grid → :class:`~jaxbelt.model.BeltModel`.

The element matrices are built with ``vmap`` (:mod:`jaxbelt.elements`), the roller kinematics
from the wrap geometry (:mod:`jaxbelt.rollers`); in 2D the static membrane stress of the aligned
machine is folded into the free-belt stiffness (:mod:`jaxbelt.prestress`), which needs a static
solve — the reason construction sits above the model, the assembly and the initial state.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from . import elements, rollers
from .control import SteeringLoops
from .lateral_theory import scene_walk_rate
from .mesh import Mesh, build_mesh
from .model import BeltModel
from .prestress import with_tension_stiffening
from .scene import Scene, SceneError


def build_model(scene: Scene, mesh: Mesh | None = None) -> BeltModel:
    """The :class:`~jaxbelt.model.BeltModel` of a validated scene (1D: model specification §2; 2D: model specification §4).

    **Arguments:** ``scene`` from :func:`jaxbelt.load_scene`; ``mesh`` its grid, default
    :func:`jaxbelt.build_mesh` of it. **Returns:** the model (physics and grid only; how to
    integrate it and what to record are :func:`jaxbelt.simulate`'s arguments). In 2D the
    membrane stress of the aligned machine's static solution stiffens the free belt where the
    scene asks for it (``[solver] tension_stiffening``, :mod:`jaxbelt.prestress`).""" 
    mesh = build_mesh(scene) if mesh is None else mesh
    return _compile_1d(scene, mesh) if scene.kind == "1d" else _compile_2d(scene, mesh)


def _node_geometry(mesh):
    on = mesh.node_roller >= 0
    j = np.maximum(mesh.node_roller, 0)
    radius = np.where(on, mesh.path.radii[j], 0.0)
    sense = np.where(on, mesh.path.senses[j], 0).astype(float)
    return dict(node_roller=jnp.asarray(mesh.node_roller), node_theta=jnp.asarray(mesh.node_theta),
                node_radius=jnp.asarray(radius), node_sense=jnp.asarray(sense), z0=jnp.asarray(mesh.z),
                contact_columns=tuple(int(i) for i in np.flatnonzero(on)),
                contact_rollers=tuple(int(mesh.node_roller[i]) for i in np.flatnonzero(on)))


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


def _structure(scene, dofs, kind, is_constraint, dynamic):
    alg = np.concatenate([np.asarray(is_constraint).reshape(-1), ~np.asarray(dynamic)])
    return dict(kind=kind, roller_names=tuple(r.name for r in scene.rollers), dofs=dofs,
                lateral_transport=scene.solver.lateral_transport,
                algebraic_index=tuple(int(i) for i in np.flatnonzero(alg)))


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
    roller_dofs = _roller_dofs(scene, mesh, rollers.DOFS_2D)
    M_r = rollers.roller_inertia_2d([r.mass for r in rl], radii, [r.width for r in rl])
    model = BeltModel(
        x=jnp.asarray(mesh.x), ell=ell, K_diag=Kd, K_lower=Kl, K_upper=Ku, f0=f0,
        R=jnp.asarray(R0), R_dz=jnp.asarray(Rdz), is_constraint=jnp.asarray(is_con),
        m_e0=elements.quad_masses(ell, w_rows, belt.density, t), M_roller=jnp.asarray(M_r),
        **_node_geometry(mesh), **roller_dofs, **_tracers(mesh),
        roller_half_width=jnp.asarray([0.5 * r.width for r in rl]),
        **_structure(scene, rollers.DOFS_2D, "2d", is_con, roller_dofs["dynamic"]),
    )
    if scene.solver.tension_stiffening:
        model = with_tension_stiffening(model, free, E, nu, t, eps0)
    if scene.control:
        model = model.replace(control=steering_loops(scene, mesh))
    return model


def steering_sign(scene: Scene, actuator: str, axis: str) -> float:
    """The sign (±1) of the steady walk rate per unit rotation of ``actuator`` about ``axis``
    (the loop's sign, :mod:`jaxbelt.control`), from the moving-beam reference
    (:func:`jaxbelt.lateral_theory.scene_walk_rate`; the sign does not depend on the tension).
    ``SceneError`` if that rotation does not steer the belt at all."""
    names = [r.name for r in scene.rollers]
    alpha = np.zeros((len(names), 3))
    alpha[names.index(actuator), "xy".index(axis)] = 1e-3
    tension = scene.belt.youngs_modulus * scene.belt.area * 1e-3  # any positive tension gives the sign
    rate = scene_walk_rate(scene, alpha, tension=tension)
    speed = max(r.speed for r in scene.rollers)
    if not abs(rate) > 1e-9 * speed:
        raise SceneError(f"control.axis = {axis!r}: a rotation of {actuator!r} about {axis} does not steer the belt "
                         "(no skew and no twist on this path); choose the other axis")
    return float(np.sign(rate))


def steering_loops(scene: Scene, mesh: Mesh) -> SteeringLoops:
    """The :class:`~jaxbelt.control.SteeringLoops` of a scene's ``[[control]]`` tables on its grid."""
    specs = scene.control
    names = [r.name for r in scene.rollers]
    d = len(rollers.DOFS_2D)
    for i, c in enumerate(specs):
        if not c.sensor[0] < mesh.length:
            raise SceneError(f"control[{i}].sensor_mm = {[c.sensor[0] * 1e3, c.sensor[1] * 1e3]}: s is off the belt "
                             f"(the path is {mesh.length * 1e3:.3f} mm long)")
    points = dataclasses.replace(mesh, tracer_x=np.array([c.sensor[0] for c in specs]),
                                 tracer_z=np.array([c.sensor[1] for c in specs]))
    loc = _tracers(points)
    n_h = max([len(c.edge_profile) for c in specs] + [1])
    prof = np.zeros((len(specs), n_h, 3))
    prof[:, :, 0] = 1.0
    for i, c in enumerate(specs):
        if c.edge_profile:
            prof[i, :len(c.edge_profile)] = np.asarray(c.edge_profile)
    arr = lambda xs: jnp.asarray(np.asarray(xs, float))  # noqa: E731
    keys = np.stack([np.asarray(jax.random.key_data(jax.random.key(c.seed))) for c in specs])
    return SteeringLoops(
        sensor_col=loc["tracer_col"], sensor_xi=loc["tracer_xi"], sensor_row=loc["tracer_row"],
        sensor_eta=loc["tracer_eta"], sensor_s=arr([c.sensor[0] for c in specs]),
        kp=arr([c.kp for c in specs]), ki=arr([c.ki for c in specs]), kd=arr([c.kd for c in specs]),
        sign=arr([steering_sign(scene, c.actuator, c.axis) for c in specs]),
        sample=arr([scene.time.dt if c.sample is None else c.sample for c in specs]),
        limit=arr([c.limit for c in specs]),
        rate_limit=arr([np.inf if c.rate_limit is None else c.rate_limit for c in specs]),
        lag=arr([c.lag for c in specs]), setpoint=arr([c.setpoint for c in specs]),
        noise=arr([c.noise for c in specs]), key=jnp.asarray(keys),
        profile_harmonic=arr(prof[:, :, 0]), profile_amplitude=arr(prof[:, :, 1]), profile_phase=arr(prof[:, :, 2]),
        loop_length=jnp.asarray(float(mesh.length)),
        actuator_dof=tuple(names.index(c.actuator) * d + rollers.DOFS_2D.index("a" + c.axis) for c in specs),
        labels=tuple(f"{c.actuator}/{c.axis}" for c in specs),
    )


def _compile_1d(scene: Scene, mesh: Mesh) -> BeltModel:
    belt, rl = scene.belt, scene.rollers
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
    roller_dofs = _roller_dofs(scene, mesh, rollers.DOFS_1D)
    return BeltModel(
        x=jnp.asarray(mesh.x), ell=ell, K_diag=Kd, K_lower=Kl, K_upper=Ku, f0=f0,
        R=jnp.asarray(R), R_dz=jnp.zeros(R.shape), is_constraint=jnp.asarray(is_con),
        m_e0=rhoA * ell, M_roller=jnp.asarray(rollers.roller_inertia_1d([r.mass for r in rl], radii)),
        **_node_geometry(mesh), **roller_dofs, **_tracers(mesh),
        roller_half_width=jnp.asarray([0.5 * r.width for r in rl]),
        **_structure(scene, rollers.DOFS_1D, "1d", is_con, roller_dofs["dynamic"]),
    )
