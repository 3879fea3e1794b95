"""Proper orthogonal decomposition and POD-Galerkin on the eliminated ODE (§5.1.2, §6.3, §7.3).

The basis comes from the SVD of snapshots of the *dynamic* unknowns before transport (the
algebraic ones are never reduced: the constraints must hold exactly, §6). The number of modes
follows the energy criterion (eq. 5.11: smallest ``r`` with ``Σ_{i≤r} σ_i² ≥ (1 - tol) Σ σ_i²``)
or the source's rule (eq. 7.2: every mode with ``σ_i² / mean(σ²) > 1e-20``).

:class:`PODGalerkin` is an integrator: each step it forms the eliminated ODE
``M̂ ẍ_f + K̂ x_f = F̂`` (eq. 3.50, Backward-Euler consistent, see
:mod:`jaxbelt.integrators.eliminated`), solves the Galerkin-projected system
``Vᵀ(M̂ + Δt² K̂)V ξ̈ = Vᵀ(F̂ - K̂ V(ξ + Δt ξ̇))`` with the dynamic state kept in the span,
``x_f = V ξ`` (the transported state is projected, ``ξ = Vᵀ x_f``), recovers the algebraic unknowns exactly
from ``x_e = g + P x_f``, and hands the full state to the (unreduced) transport step, as the
source did. With all modes it reproduces the eliminated integrator.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from ..integrators import AbstractIntegrator
from ..integrators.eliminated import eliminated_system, recover_state
from ..linalg import join


@functools.partial(jax.custom_jvp, nondiff_argnums=(1,))
def truncated_svd(X, r: int):
    """Leading ``r`` left singular vectors and values of ``X``: ``(U_r (N, r), s_r (r,))``.

    Differentiable with a JVP that divides only by differences between a *kept* and any other
    singular value: with the thin SVD ``X = U S Vᵀ`` (k = min(N, m) values), ``dP = Uᵀ dX V``
    and ``F_ij = 1/(s_j² - s_i²)``, column ``j < r`` of ``dU`` is
    ``Σ_{i≠j} u_i F_ij (dP_ij s_j + s_i dP_ji) + (I - U Uᵀ) dX v_j / s_j`` and ``ds_j = dP_jj``
    (Townsend 2016). It is the exact derivative; the plain SVD rule also divides by
    differences between *dropped* values, and snapshot matrices have many numerically zero,
    nearly equal ones, which turns gradients into NaN. Needs the kept singular values distinct,
    non-zero and apart from the dropped ones.
    """
    U, s, _ = jnp.linalg.svd(X, full_matrices=False)
    return U[:, :r], s[:r]


@truncated_svd.defjvp
def _truncated_svd_jvp(r, primals, tangents):
    (X,), (dX,) = primals, tangents
    U, s, Vh = jnp.linalg.svd(X, full_matrices=False)
    V = Vh.T
    dP = U.T @ dX @ V[:, :r]  # (k, r)
    dPt = (U[:, :r].T @ dX @ V).T  # (k, r): entries dP_ji
    sk, sr = s, s[:r]
    same = jnp.arange(s.shape[0])[:, None] == jnp.arange(r)[None, :]
    diff = sr[None, :] ** 2 - sk[:, None] ** 2
    F = jnp.where(same, 0.0, 1.0 / jnp.where(same, 1.0, diff))
    inner = F * (dP * sr[None, :] + sk[:, None] * dPt)
    dXV = dX @ V[:, :r]
    dU = U @ inner + (dXV - U @ (U.T @ dXV)) / sr[None, :]
    return (U[:, :r], sr), (dU, jnp.diagonal(dP[:r]))


def pod_basis(X, n_modes: int | None = None, energy_tol: float | None = None, rule: str | None = None):
    """POD modes of snapshots ``X`` (N, m): ``(V (N, r), singular values (min(N, m),))``.

    Exactly one of ``n_modes``, ``energy_tol`` (eq. 5.11) or ``rule="source"`` (eq. 7.2). The
    basis is differentiable w.r.t. ``X`` (:func:`truncated_svd`); the rules that look at the
    singular values need concrete data, so under ``jax.grad`` give ``n_modes``."""
    X = jnp.asarray(X)
    if not isinstance(X, jax.core.Tracer):  # concrete data: one SVD gives the values and the basis
        U, s, _ = jnp.linalg.svd(X, full_matrices=False)
        return U[:, :choose_modes(np.asarray(s), n_modes, energy_tol, rule)], s
    # traced (grad/jit): the differentiable truncated SVD, and the values apart for the caller
    s = jnp.linalg.svd(jax.lax.stop_gradient(X), compute_uv=False)
    if n_modes is None or energy_tol is not None or rule is not None:
        raise ValueError("under jax.grad or jit give n_modes: the mode rules need concrete singular values")
    return truncated_svd(X, int(min(n_modes, min(X.shape))))[0], s


def choose_modes(s, n_modes=None, energy_tol=None, rule=None) -> int:
    """Number of modes from the singular values ``s`` (descending)."""
    if sum(v is not None for v in (n_modes, energy_tol, rule)) != 1:
        raise ValueError("give exactly one of n_modes, energy_tol, rule")
    e = np.asarray(s, float) ** 2
    if n_modes is not None:
        return int(min(n_modes, len(e)))
    if energy_tol is not None:
        return int(np.searchsorted(np.cumsum(e) / e.sum(), 1.0 - energy_tol) + 1)
    if rule == "source":
        return int(np.sum(e / e.mean() > 1e-20))
    raise ValueError(f"unknown rule {rule!r}")


class PODGalerkin(AbstractIntegrator):
    """Backward Euler on the Galerkin projection of the eliminated ODE onto ``basis``.

    **Fields:** ``basis`` (N_dynamic, r) orthonormal, on the dynamic unknowns of the model's
    partition (``model.partition``) in their order; ``transport`` the transport rule that follows
    each step (as every integrator's)."""

    basis: jax.Array  # (N_dynamic, r)

    def step(self, model, state, dt, run_data=None):
        V = self.basis
        dyn_idx, alg_idx = model.partition
        M_hat, K_hat, F_hat, P, g, _ = eliminated_system(model, state, dt, dyn_idx, alg_idx)
        f = jnp.asarray(dyn_idx)
        # the state is kept in the span of the basis: x_f = V ξ, ẋ_f = V ξ̇
        xi, xi_dot = V.T @ join(state.u, state.chi)[f], V.T @ join(state.u_dot, state.chi_dot)[f]
        A_r = V.T @ (M_hat + dt**2 * K_hat) @ V
        xi_ddot = jnp.linalg.solve(A_r, V.T @ (F_hat - K_hat @ (V @ (xi + dt * xi_dot))))
        xi_dot = xi_dot + dt * xi_ddot
        return recover_state(state, dt, V @ (xi + dt * xi_dot), V @ xi_dot, P, g, dyn_idx, alg_idx)


def fit_pod(model, snapshots, transport: str = "shift", **choice) -> PODGalerkin:
    """POD-Galerkin integrator from full snapshots ``snapshots`` (N, m) of ``model`` (or of
    several configurations stacked side by side); ``choice`` as :func:`pod_basis`; ``transport``
    the rule of the runs it is used in."""
    dyn, _ = model.partition
    V, _ = pod_basis(jnp.asarray(snapshots)[jnp.asarray(dyn)], **choice)
    return PODGalerkin(V, transport=transport)
