"""Roller kinematics and inertia (:mod:`jaxbelt.rollers`) against independent geometry: a point of the
roller surface moved by the roller's rigid motion (scipy's rotations, extrinsic x → y → z), projected
on the belt tangent and the width direction, gives the exact static displacement and, for small
motions, the no-slip rows ``R_r χ``; the inertias against midpoint quadrature over a solid cylinder."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from jaxbelt.rollers import (exact_static_displacement, roller_constraint_rows_1d, roller_constraint_rows_2d,
                             roller_inertia_1d, roller_inertia_2d, rotation_xyz)

# five node columns: two on roller 0 (sense +1), one free, two on roller 1 (sense −1)
NODE_ROLLER = np.array([0, 0, -1, 1, 1])
NODE_THETA = np.array([0.3, 1.7, 0.0, -2.0, 2.9])
SENSES = np.array([1, -1])
RADII = np.array([0.05, 0.03])
Z = np.array([-0.02, 0.0, 0.015])


def _moved(chi, z):
    """``(u, v)`` per node and row by rigid motion of the roller surface point (numpy, scipy)."""
    out = np.zeros((len(NODE_ROLLER), 2 * len(z)))
    for i, j in enumerate(NODE_ROLLER):
        if j < 0:
            continue
        th, s, r = NODE_THETA[i], SENSES[j], RADII[j]
        d, a = chi[j, :3], chi[j, 3:]
        Q = Rotation.from_euler("xyz", [a[0], a[1], 0.0]).as_matrix()
        t = s * np.array([-np.sin(th), np.cos(th), 0.0])
        for k, zk in enumerate(z):
            p0 = np.array([r * np.cos(th), r * np.sin(th), zk])
            delta = d + Q @ p0 - p0
            out[i, 2 * k], out[i, 2 * k + 1] = delta @ t, delta[2]
    return out


def test_rotation_is_the_extrinsic_x_then_y_then_z_rotation():
    a = (0.3, -0.7, 1.1)
    Q = np.asarray(rotation_xyz(*map(jnp.asarray, a)))
    np.testing.assert_allclose(Q, Rotation.from_euler("xyz", a).as_matrix(), atol=1e-15)
    np.testing.assert_allclose(Q @ Q.T, np.eye(3), atol=1e-15)


def test_exact_static_displacement_equals_the_rigid_motion_of_the_surface_points():
    chi = np.random.default_rng(0).standard_normal((2, 6)) * np.array([2e-3, 2e-3, 2e-3, 0.05, 0.05, 0.3])
    got = jax.jit(exact_static_displacement)(jnp.asarray(chi), jnp.asarray(NODE_ROLLER), jnp.asarray(NODE_THETA),
                                    jnp.asarray(RADII[np.maximum(NODE_ROLLER, 0)]),
                                    jnp.asarray(SENSES[np.maximum(NODE_ROLLER, 0)]), jnp.asarray(Z))
    np.testing.assert_allclose(np.asarray(got), _moved(chi, Z), atol=1e-16)
    assert np.all(np.asarray(got)[2] == 0.0)


def test_two_d_rows_are_the_linearised_rigid_motion():
    """``R0 χ`` equals the moved surface points to first order: the remainder shrinks as ``|χ|²``;
    α_z moves the surface point ``s r α_z`` along the belt."""
    R0, _ = roller_constraint_rows_2d(NODE_ROLLER, NODE_THETA, SENSES, RADII, Z)
    direction = np.random.default_rng(1).standard_normal((2, 6))
    direction[:, 5] = 0.0  # α_z: a rotation about the axis, checked below
    errors = []
    for eps in (1e-3, 1e-4):
        chi = eps * direction
        errors.append(np.abs(R0 @ chi.reshape(-1) - _moved(chi, Z)).max())
    assert errors[1] < errors[0] / 50 and errors[1] < 1e-9
    az = np.zeros(12)
    az[5], az[11] = 1.0, 1.0
    u = (R0 @ az)[:, 0::2]
    np.testing.assert_allclose(u[[0, 1, 3, 4]], (SENSES * RADII)[[0, 0, 1, 1]][:, None] * np.ones((4, 3)), rtol=1e-15)
    assert np.all((R0 @ az)[:, 1::2] == 0)


def test_lever_arm_derivative_is_the_rows_change_with_z():
    R0, Rdz = roller_constraint_rows_2d(NODE_ROLLER, NODE_THETA, SENSES, RADII, Z)
    R1, _ = roller_constraint_rows_2d(NODE_ROLLER, NODE_THETA, SENSES, RADII, Z + 1e-3)
    np.testing.assert_allclose((R1 - R0) / 1e-3, Rdz, atol=1e-12)
    assert np.all(Rdz[:, 1::2] == 0) and np.all(R0[2] == 0) and np.all(Rdz[2] == 0)


def test_one_d_rows_are_the_tangential_motion_of_dx_and_the_surface_speed_of_az():
    R = roller_constraint_rows_1d(NODE_ROLLER, NODE_THETA, SENSES, RADII)
    assert R.shape == (5, 1, 4)
    chi2d = np.zeros((2, 6))
    chi2d[:, 0] = [1e-6, -2e-6]
    u_dx = _moved(chi2d, [0.0])[:, 0]
    np.testing.assert_allclose(R[:, 0] @ np.array([1e-6, 0, -2e-6, 0]), u_dx, atol=1e-18)  # linear in dx: exact
    np.testing.assert_allclose(R[[0, 1, 3, 4], 0, [1, 1, 3, 3]], (SENSES * RADII)[[0, 0, 1, 1]])
    assert np.all(R[2] == 0)


def _cylinder_moments(m, r, w, n=60):
    """``(∫ (x² + y²) dm, ∫ (y² + z²) dm)`` over a solid cylinder of axis z (midpoint rule)."""
    rho = (np.arange(n) + 0.5) / n * r
    th = (np.arange(n) + 0.5) / n * 2 * np.pi
    z = (np.arange(n) + 0.5) / n * w - w / 2
    P, T, Zg = np.meshgrid(rho, th, z, indexing="ij")
    dm = m / (np.pi * r ** 2 * w) * P * (r / n) * (2 * np.pi / n) * (w / n)
    return float(np.sum(P ** 2 * dm)), float(np.sum(((P * np.sin(T)) ** 2 + Zg ** 2) * dm))


@pytest.mark.parametrize("m,r,w", [(0.5, 0.05, 0.06), (2.0, 0.03, 0.2)])
def test_inertias_are_those_of_a_solid_cylinder(m, r, w):
    Iz, Ix = _cylinder_moments(m, r, w)
    np.testing.assert_allclose(roller_inertia_1d([m, 2 * m], [r, r]), [m, Iz, 2 * m, 2 * Iz], rtol=1e-3)
    np.testing.assert_allclose(roller_inertia_2d([m], [r], [w]), [m, m, m, Ix, Ix, Iz], rtol=1e-3)
