"""Roller kinematics and inertia: the no-slip map ``R_r`` and the roller mass matrix.

1D (§3.2, model specification §2): each roller has the unknowns ``χ_j = (d_x, α_z)``. A belt node on
roller ``j`` at wrap angle θ moves along the belt by the tangential component of the
translation plus the surface motion of the rotation,

$$ u = R_r χ_j = s_j(-\\sin θ)\\, d_x + s_j r_j\\, α_z ,$$

with ``t(θ) = s_j(-\\sin θ, \\cos θ)`` the unit tangent in the direction of motion. The same row
gives the constraint (eq. 3.35) and, transposed, the generalised belt force on the roller
(eq. 3.38–3.39 written by virtual work).
"""

from __future__ import annotations

import numpy as np

DOFS_1D = ("dx", "az")
DOFS_2D = ("dx", "dy", "dz", "ax", "ay", "az")


def roller_constraint_rows_1d(node_roller, node_theta, senses, radii):
    """``R`` for every node column, shape (n_xi, 1, 2p); zero rows for free-belt nodes."""
    n, p = len(node_roller), len(radii)
    R = np.zeros((n, 1, 2 * p))
    on = node_roller >= 0
    j = node_roller[on]
    s = senses[j]
    R[on, 0, 2 * j] = s * (-np.sin(node_theta[on]))
    R[on, 0, 2 * j + 1] = s * radii[j]
    return R


def roller_inertia_1d(masses, radii):
    """Diagonal roller inertia for ``(d_x, α_z)``: ``m`` and ``I_z = ½ m r²`` (solid cylinder)."""
    masses, radii = np.asarray(masses, float), np.asarray(radii, float)
    return np.stack([masses, 0.5 * masses * radii**2], axis=1).reshape(-1)


# ----------------------------------------------------------------------------- 2D (model specification §4)


def roller_constraint_rows_2d(node_roller, node_theta, senses, radii, z):
    """``R_r`` at the reference lever arm ``z`` and its derivative w.r.t. the lever arm.

    For a node on roller ``j`` at wrap angle θ and lateral position ``z`` (model specification §4):

        u = s (-d_x sin θ + d_y cos θ - z α_x cos θ - z α_y sin θ + r α_z)
        v = d_z + r (α_x sin θ - α_y cos θ)

    The lever arm is the node's *current* lateral position ``z + v`` (weak nonlinearity §4.2):
    ``R(v) = R0 + R_dz · v`` on the u-rows.

    No ``∂v/∂α_z`` cross term is added for the lateral surface velocity of a skewed roller
    (model specification §3): the transport step carries ``w = v - v_s(θ)`` along the arc, so material
    on the roller follows the static surface profile ``v_s(θ) = d_z + r(α_x sin θ - α_y cos θ)``,
    whose rate along the rotation ``θ̇ = sV/r`` is exactly ``V ψ(θ)``,
    ``ψ = s(α_x cos θ + α_y sin θ)``. Adding the cross term as well would count it twice.

    **Returns:** ``(R0, R_dz)``, each (n_xi, 2 n_eta, 6p); DOFs per roller (dx, dy, dz, ax, ay, az).
    """
    n, n_eta, p = len(node_roller), len(z), len(radii)
    R0 = np.zeros((n, 2 * n_eta, 6 * p))
    Rdz = np.zeros_like(R0)
    on = np.flatnonzero(node_roller >= 0)
    for i in on:
        j = node_roller[i]
        th, s, r, c = node_theta[i], senses[j], radii[j], 6 * j
        sn, cs = np.sin(th), np.cos(th)
        for k in range(n_eta):
            ru, rv = 2 * k, 2 * k + 1
            R0[i, ru, c:c + 6] = s * np.array([-sn, cs, 0.0, -z[k] * cs, -z[k] * sn, r])
            Rdz[i, ru, c + 3], Rdz[i, ru, c + 4] = -s * cs, -s * sn
            R0[i, rv, c + 2], R0[i, rv, c + 3], R0[i, rv, c + 4] = 1.0, r * sn, -r * cs
    return R0, Rdz


def roller_inertia_2d(masses, radii, widths):
    """``diag(m, m, m, I_x, I_y, I_z)`` per roller: solid cylinder, ``I_z = ½ m r²``,
    ``I_x = I_y = m (3 r² + w²) / 12``."""
    m, r, w = (np.asarray(a, float) for a in (masses, radii, widths))
    Ixy = m * (3 * r**2 + w**2) / 12.0
    return np.stack([m, m, m, Ixy, Ixy, 0.5 * m * r**2], axis=1).reshape(-1)


def rotation_xyz(ax, ay, az):
    """``R_z(α_z) R_y(α_y) R_x(α_x)``: rotations applied about x, then y, then z (§4.2)."""
    import jax.numpy as jnp

    cx, sx, cy, sy, cz, sz = jnp.cos(ax), jnp.sin(ax), jnp.cos(ay), jnp.sin(ay), jnp.cos(az), jnp.sin(az)
    one, zero = jnp.ones_like(ax), jnp.zeros_like(ax)
    Rx = jnp.array([[one, zero, zero], [zero, cx, -sx], [zero, sx, cx]])
    Ry = jnp.array([[cy, zero, sy], [zero, one, zero], [-sy, zero, cy]])
    Rz = jnp.array([[cz, -sz, zero], [sz, cz, zero], [zero, zero, one]])
    return Rz @ Ry @ Rx


def exact_static_displacement(chi, node_roller, node_theta, node_radius, node_sense, z):
    """Belt-plane displacement (n, 2 n_eta) of roller nodes under the *finite* static motion
    ``p' = d + R_z R_y R_x p₀`` of their roller, ``p₀ = r n(θ) + z e_z`` (§4.2): ``u = δ·t``,
    ``v = δ·e_z``. Pure ``jnp`` (differentiable in ``chi`` (p, 6)); zero on free nodes."""
    import jax
    import jax.numpy as jnp

    j = jnp.maximum(node_roller, 0)
    c = chi[j]  # (n, 6)
    Q = jax.vmap(lambda a: rotation_xyz(a[3], a[4], jnp.zeros_like(a[5])))(c)  # (n, 3, 3)
    n_vec = jnp.stack([jnp.cos(node_theta), jnp.sin(node_theta), jnp.zeros_like(node_theta)], axis=1)
    t_vec = node_sense[:, None] * jnp.stack([-jnp.sin(node_theta), jnp.cos(node_theta),
                                             jnp.zeros_like(node_theta)], axis=1)
    p0 = node_radius[:, None, None] * n_vec[:, None, :] + z[None, :, None] * jnp.array([0.0, 0.0, 1.0])
    p1 = c[:, None, :3] + jnp.einsum("nab,nkb->nka", Q, p0)
    delta = p1 - p0  # (n, n_eta, 3)
    u = jnp.einsum("nka,na->nk", delta, t_vec)
    v = delta[:, :, 2]
    out = jnp.stack([u, v], axis=2).reshape(node_roller.shape[0], -1)
    return jnp.where((node_roller >= 0)[:, None], out, 0.0)
