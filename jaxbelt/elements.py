"""Free-belt element matrices, built for all elements at once with ``vmap`` (§3.1.4, §4.1.3).

An *element column* ``i`` joins node column ``i`` to ``i+1``. Its matrices act on the
``2b`` DOFs of the two columns (``b`` per column): ``[column i; column i+1]``. In 1D
(``b = 1``) this is the two-node bar; :func:`column_pair_to_blocks` scatters them into the
cyclic block-tridiagonal format of :mod:`jaxbelt.linalg`.
"""

from __future__ import annotations

import functools

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

GAUSS_POINTS = (0.5 - 0.5 / 3**0.5, 0.5 + 0.5 / 3**0.5)  # 2-point Gauss rule on [0, 1]


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
    for gx in GAUSS_POINTS:
        for gz in GAUSS_POINTS:
            B = quad_B(gx, gz, ell, w)
            K = K + B.T @ D @ B
    return t * K * (ell * w / 4.0)


def quad_bubble_B(xi, eta, ell, w):
    """Strain matrix (3 × 4) of the incompatible (bubble) modes of the ``ℓ × w`` rectangle at
    ``(ξ, η) ∈ [0, 1]²``: ``P₁ = 4ξ(1 − ξ)``, ``P₂ = 4η(1 − η)``, internal DOFs
    ``[a_u1, a_v1, a_u2, a_v2]`` with ``u += a_u1 P₁ + a_u2 P₂``, ``v += a_v1 P₁ + a_v2 P₂``.
    ``∫ B dA = 0`` on a rectangle, so the modes do no work on a constant stress (patch test)."""
    d1 = 4.0 * (1.0 - 2.0 * xi) / ell  # ∂P₁/∂x
    d2 = 4.0 * (1.0 - 2.0 * eta) / w  # ∂P₂/∂z
    z = jnp.zeros_like(d1)
    return jnp.stack([jnp.stack([d1, z, z, z]), jnp.stack([z, z, z, d2]), jnp.stack([z, d1, d2, z])])


def quad_qm6_stiffness(ell, w, E, nu, t):
    """Bilinear rectangle with Wilson–Taylor incompatible modes (QM6), the 4 bubble DOFs
    statically condensed: ``K = K_cc − K_ci K_ii⁻¹ K_ic`` (8 × 8, same DOFs as :func:`quad_stiffness`).

    The bubbles add the quadratic ``x²`` and ``z²`` shapes the bilinear quad lacks, so a
    rectangle bends without the parasitic shear (and Poisson) strain that makes :func:`quad_stiffness`
    lock when it is long (ℓ ≫ h) in in-plane bending; on rectangles Wilson's Q6 and Taylor's QM6 are
    the same element, pure bending is exact and constant strain is reproduced exactly (patch test).
    All integrands are at most quadratic: 2 × 2 Gauss is exact.

    Measured (``benchmarks/bending_locking.py``, clamped–clamped strip L/w = 100 under a central
    lateral load, against Timoshenko): with 2 elements across (n_eta = 3) the bilinear quad gives
    FE/beam = 0.89 at ℓ/h = 1, 0.30 at ℓ/h = 5 and 0.10 at ℓ/h = 10 (0.88 at ℓ/h = 10 even with
    17 elements across); QM6 gives 0.98–1.00 over the whole range, 0.999 at n_eta = 18.

    Default (``[mesh] element``, :data:`DEFAULT_ELEMENT`): ``"qm6"``. It costs nothing per time
    step (condensed at compile time into the same 8 × 8 blocks; +0.02 s compile on the default
    scene) and removes the locking wherever the mesh is coarse across a narrow belt. On the source's
    default mesh (near-square 27 × 23.5 mm elements, 17 across) it hardly changes the results:
    over the whole 100 s of ``three-roller-t72`` the tracer displacements move by at most
    1.1e-4 mm in u (of 1.86 mm, 6e-5) and 1.2e-5 mm in v (of 0.041 mm, 3e-4); coarsened to
    n_eta = 5, 8.3e-4 mm and 1.6e-4 mm (4e-4, 4e-3). ``element = "q4"`` keeps the plain bilinear
    quad (bit-for-bit the earlier model). With tension stiffening, :mod:`jaxbelt.prestress` recovers
    the membrane stress from the bilinear part (the bubbles' share, up to ~6–9 % of the peak stress
    near contact lines and ~1–2 % of the peak of ``K_σ`` on ``three-roller-tension``, is left out).
    """
    D = plane_stress_D(E, nu)
    Kcc, Kci, Kii = jnp.zeros((8, 8)), jnp.zeros((8, 4)), jnp.zeros((4, 4))
    for gx in GAUSS_POINTS:
        for gz in GAUSS_POINTS:
            Bc, Bi = quad_B(gx, gz, ell, w), quad_bubble_B(gx, gz, ell, w)
            Kcc = Kcc + Bc.T @ D @ Bc
            Kci = Kci + Bc.T @ D @ Bi
            Kii = Kii + Bi.T @ D @ Bi
    K = Kcc - Kci @ jnp.linalg.solve(Kii, Kci.T)
    K = 0.5 * (K + K.T)  # exact symmetry after the condensation's round-off
    return t * K * (ell * w / 4.0)


QUAD_ELEMENTS = {"q4": quad_stiffness, "qm6": quad_qm6_stiffness}
DEFAULT_ELEMENT = "qm6"


def quad_prestress_force(ell, w, E, eps0, t):
    """Nodal internal forces (8,) of a uniaxial pre-stress ``σ₀ = (E ε₀, 0, 0)`` (pre-tension)."""
    sig = jnp.array([E * eps0, 0.0, 0.0])
    f = jnp.zeros(8)
    for gx in GAUSS_POINTS:
        for gz in GAUSS_POINTS:
            f = f + quad_B(gx, gz, ell, w).T @ sig
    return t * f * (ell * w / 4.0)


def quad_dofs(n_eta):
    """Column-pair DOF indices (n_eta-1, 8) of every quad in an element column."""
    b = 2 * n_eta
    j = jnp.arange(n_eta - 1)[:, None]
    return jnp.concatenate([2 * j, 2 * j + 1, 2 * j + 2, 2 * j + 3, b + 2 * j, b + 2 * j + 1,
                            b + 2 * j + 2, b + 2 * j + 3], axis=1)


@functools.partial(jax.jit, static_argnames=("element",))
def free_belt_stiffness_2d(ell, w_rows, elem_free, E, nu, t, element="q4"):
    """Blocks (n, b, b) of ``K_f`` for the plane-stress belt; element matrices of all
    ``n_xi × (n_eta - 1)`` quads at once with ``vmap``. ``element``: ``"q4"`` (bilinear,
    :func:`quad_stiffness`) or ``"qm6"`` (incompatible modes, :func:`quad_qm6_stiffness`)."""
    if element not in QUAD_ELEMENTS:
        raise ValueError(f"element = {element!r}: must be one of {', '.join(QUAD_ELEMENTS)}")
    n, n_eta = ell.shape[0], w_rows.shape[0] + 1
    Kq = jax.vmap(jax.vmap(QUAD_ELEMENTS[element], in_axes=(None, 0, None, None, None)),
                  in_axes=(0, None, None, None, None))(ell, w_rows, E, nu, t)  # (n, n_eta-1, 8, 8)
    Kq = Kq * elem_free[:, None, None, None]
    idx = quad_dofs(n_eta)
    Kc = jnp.zeros((n, 4 * n_eta, 4 * n_eta)).at[:, idx[:, :, None], idx[:, None, :]].add(Kq)
    return column_pair_to_blocks(Kc)


@jax.jit
def prestress_force_2d(ell, w_rows, elem_free, E, eps0, t):
    """Nodal internal force ``f₀`` (n, b) of the pre-tension on the free elements."""
    n, n_eta = ell.shape[0], w_rows.shape[0] + 1
    fq = jax.vmap(jax.vmap(quad_prestress_force, in_axes=(None, 0, None, None, None)),
                  in_axes=(0, None, None, None, None))(ell, w_rows, E, eps0, t) * elem_free[:, None, None]
    fc = jnp.zeros((n, 4 * n_eta)).at[:, quad_dofs(n_eta)].add(fq)
    return column_pair_to_nodes(fc)


def quad_masses(ell, w_rows, rho, t):
    """Element masses ``ρ t ℓ w`` (n, n_eta - 1); a quarter goes to each node (eq. 4.24)."""
    return rho * t * ell[:, None] * w_rows[None, :]
