"""Roller kinematics and inertia: the no-slip map ``R_r`` and the roller mass matrix.

1D (§3.2, MODEL.md §2): each roller has the unknowns ``χ_j = (d_x, α_z)``. A belt node on
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
