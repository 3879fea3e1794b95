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


def bar_lumped_mass(ell, rhoA):
    """Lumped (Newton–Cotes) element mass ``ρAℓ`` split half to each end (eq. 3.25–3.26)."""
    return rhoA * ell


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
