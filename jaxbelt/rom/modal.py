"""Modal decomposition of the eliminated ODE (§5.1.1, §6.2, eq. 5.5–5.7).

``K̂ φ = ω² M̂ φ`` on the dynamic unknowns (the algebraic ones are eliminated first: on the DAE
the singular mass matrix gives infinite frequencies, §6.2). ``M̂`` and ``K̂`` of the belt are
symmetric up to round-off; they are symmetrised, ``M̂ = L Lᵀ`` (Cholesky) and the symmetric
problem ``L⁻¹ K̂ L⁻ᵀ y = ω² y`` is solved, so the modes ``Φ = L⁻ᵀ Y`` are M-orthonormal.

Two orderings: by frequency, and the source's proposal of §6.2 that accounts for the forcing —
modes ranked by ``|φᵢᵀ F̂| / ωᵢ`` (large projection on the right-hand side and low frequency first).
"""

from __future__ import annotations

import jax.numpy as jnp

from ..integrators import algebraic_partition
from ..integrators.eliminated import eliminated_system


def modal_basis(model, state):
    """``(omega (N_f,), Phi (N_f, N_f), F_hat (N_f,))`` at ``state``, by ascending frequency."""
    dyn, alg = algebraic_partition(model)
    M_hat, K_hat, F_hat, _, _, p = eliminated_system(model, state, dyn, alg)
    M = 0.5 * (M_hat + M_hat.T)
    K = 0.5 * (K_hat + K_hat.T)
    L = jnp.linalg.cholesky(M)
    Li = jnp.linalg.inv(L)
    w2, Y = jnp.linalg.eigh(Li @ K @ Li.T)
    Phi = Li.T @ Y
    # forcing of the ODE at this step: F̂ - K̂ (x + Δt ẋ) is what drives the modes
    force = F_hat - K_hat @ p[jnp.asarray(dyn)]
    return jnp.sqrt(jnp.clip(w2, 0.0)), Phi, force


def forcing_order(omega, Phi, force):
    """Indices ranking modes by ``|φᵀ F| / ω`` (descending), the ordering proposed in §6.2."""
    score = jnp.abs(Phi.T @ force) / jnp.maximum(omega, 1e-300)
    return jnp.argsort(-score)
