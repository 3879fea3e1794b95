"""Free-belt element matrices, built for all elements at once with ``vmap`` (§3.1.4, §4.1.3).

An *element column* ``i`` joins node column ``i`` to ``i+1``. Its matrices act on the
``2b`` DOFs of the two columns (``b`` per column): ``[column i; column i+1]``. In 1D
(``b = 1``) this is the two-node bar; :func:`column_pair_to_blocks` scatters them into the
cyclic block-tridiagonal format of :mod:`jaxbelt.linalg`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def bar_stiffness(ell, EA):
    """Two-node bar: ``K_e = EA/ℓ [[1, -1], [-1, 1]]`` (eq. 3.27–3.30)."""
    k = EA / ell
    return k * jnp.array([[1.0, -1.0], [-1.0, 1.0]])


def bar_prestress_force(EA, eps0):
    """Nodal internal forces of a bar with initial strain ``ε₀`` (pre-tension): ``EA ε₀ [-1, 1]``."""
    return EA * eps0 * jnp.array([-1.0, 1.0])


def column_pair_to_blocks(Ke):
    """Scatter element-column matrices (n, 2b, 2b) into ``(diag, lower, upper)`` blocks (n, b, b)."""
    b = Ke.shape[1] // 2
    diag = Ke[:, :b, :b] + jnp.roll(Ke[:, b:, b:], 1, axis=0)
    upper = Ke[:, :b, b:]
    lower = jnp.roll(Ke[:, b:, :b], 1, axis=0)
    return diag, lower, upper


def column_pair_to_nodes(fe):
    """Scatter element-column vectors (n, 2b) onto node columns (n, b)."""
    b = fe.shape[1] // 2
    return fe[:, :b] + jnp.roll(fe[:, b:], 1, axis=0)


def free_belt_stiffness_1d(ell, elem_free, EA):
    """Blocks of the free-belt stiffness ``K_f`` of the string (roller elements contribute none)."""
    Ke = jax.vmap(bar_stiffness, in_axes=(0, None))(ell, EA) * elem_free[:, None, None]
    return column_pair_to_blocks(Ke)


def prestress_force_1d(elem_free, EA, eps0):
    """Nodal internal force ``f₀`` of the pre-tension on the free elements, shape (n, 1)."""
    fe = bar_prestress_force(EA, eps0)[None, :] * elem_free[:, None]
    return column_pair_to_nodes(fe)


# ----------------------------------------------------------------------------- 2D plane stress

_GAUSS = (0.5 - 0.5 / 3**0.5, 0.5 + 0.5 / 3**0.5)


def plane_stress_D(E, nu):
    """Plane-stress elasticity matrix (eq. 4.3) for ``[ε_x, ε_z, γ_xz]``."""
    return E / (1.0 - nu**2) * jnp.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, 0.5 * (1.0 - nu)]])


def quad_B(xi, eta, ell, w):
    """Strain-displacement matrix (eq. 4.15) of the bilinear rectangle ``ℓ × w`` at local
    coordinates ``(ξ, η) ∈ [0, 1]²``. Node order (eq. 4.11): ``(i, j), (i, j+1), (i+1, j),
    (i+1, j+1)``; DOFs interleaved ``u, v``."""
    dNdx = jnp.array([-(1 - eta), -eta, 1 - eta, eta]) / ell
    dNdz = jnp.array([-(1 - xi), 1 - xi, -xi, xi]) / w
    z4 = jnp.zeros(4)
    row_x = jnp.stack([dNdx, z4], axis=1).reshape(-1)
    row_z = jnp.stack([z4, dNdz], axis=1).reshape(-1)
    row_g = jnp.stack([dNdz, dNdx], axis=1).reshape(-1)
    return jnp.stack([row_x, row_z, row_g])


def quad_stiffness(ell, w, E, nu, t):
    """``K_e = t ∫ Bᵀ D B`` (eq. 4.21) by 2 × 2 Gauss quadrature, exact on rectangles (8 × 8)."""
    D = plane_stress_D(E, nu)
    K = jnp.zeros((8, 8))
    for gx in _GAUSS:
        for gz in _GAUSS:
            B = quad_B(gx, gz, ell, w)
            K = K + B.T @ D @ B
    return t * K * (ell * w / 4.0)


def quad_prestress_force(ell, w, E, eps0, t):
    """Nodal internal forces (8,) of a uniaxial pre-stress ``σ₀ = (E ε₀, 0, 0)`` (pre-tension)."""
    sig = jnp.array([E * eps0, 0.0, 0.0])
    f = jnp.zeros(8)
    for gx in _GAUSS:
        for gz in _GAUSS:
            f = f + quad_B(gx, gz, ell, w).T @ sig
    return t * f * (ell * w / 4.0)


def _quad_dofs(n_eta):
    """Column-pair DOF indices (n_eta-1, 8) of every quad in an element column."""
    b = 2 * n_eta
    j = jnp.arange(n_eta - 1)[:, None]
    return jnp.concatenate([2 * j, 2 * j + 1, 2 * j + 2, 2 * j + 3, b + 2 * j, b + 2 * j + 1,
                            b + 2 * j + 2, b + 2 * j + 3], axis=1)


def free_belt_stiffness_2d(ell, w_rows, elem_free, E, nu, t):
    """Blocks (n, b, b) of ``K_f`` for the plane-stress belt; element matrices of all
    ``n_xi × (n_eta - 1)`` quads at once with ``vmap``."""
    n, n_eta = ell.shape[0], w_rows.shape[0] + 1
    Kq = jax.vmap(jax.vmap(quad_stiffness, in_axes=(None, 0, None, None, None)),
                  in_axes=(0, None, None, None, None))(ell, w_rows, E, nu, t)  # (n, n_eta-1, 8, 8)
    Kq = Kq * elem_free[:, None, None, None]
    idx = _quad_dofs(n_eta)
    Kc = jnp.zeros((n, 4 * n_eta, 4 * n_eta)).at[:, idx[:, :, None], idx[:, None, :]].add(Kq)
    return column_pair_to_blocks(Kc)


def prestress_force_2d(ell, w_rows, elem_free, E, eps0, t):
    """Nodal internal force ``f₀`` (n, b) of the pre-tension on the free elements."""
    n, n_eta = ell.shape[0], w_rows.shape[0] + 1
    fq = jax.vmap(jax.vmap(quad_prestress_force, in_axes=(None, 0, None, None, None)),
                  in_axes=(0, None, None, None, None))(ell, w_rows, E, eps0, t) * elem_free[:, None, None]
    fc = jnp.zeros((n, 4 * n_eta)).at[:, _quad_dofs(n_eta)].add(fq)
    return column_pair_to_nodes(fc)


def quad_masses(ell, w_rows, rho, t):
    """Element masses ``ρ t ℓ w`` (n, n_eta - 1); a quarter goes to each node (eq. 4.24)."""
    return rho * t * ell[:, None] * w_rows[None, :]
