"""The tolerance box on the linear model of the response: its worst case, the largest box under a
limit, and the statistical (RSS) stack-up.

A *tolerance box* is a vector of half-widths ``h`` (P,) ≥ 0 around the scene's own
misalignment: every configuration ``θ`` with ``|θ_k| ≤ h_k`` must keep the metric at or below
the limit. The response is nearly linear in the misalignments (model specification §6),
``r(θ) ≈ r₀ + J θ`` (:func:`jaxbelt.design.sensitivity.response_jacobian`), so the worst case
over the box is known in closed form or nearly so:

- max-type metrics (``lateral_max``, ``lateral_peak``, ``walk_rate``):
  $W(h) = \\max_i \\big(|r_{0,i}| + \\sum_k |J_{ik}| h_k\\big)$, reached at the corner
  ``θ_k = sign(r₀ᵢ) sign(J_ik) h_k`` of the worst row ``i`` — exact for the linear model;
- RMS metrics: ``‖r₀ + J θ‖/√n`` is convex, so its maximum over the box is at a corner; all
  ``2^P`` corners are enumerated for ``P ≤ 16``, otherwise the candidates are the sign corners
  of every row and of the leading right singular vectors, improved by single sign flips
  (a heuristic, which the verification by full runs then checks).

The half-widths maximise the weighted log-volume $\\sum_k w_k \\log h_k$ (a component with a
larger weight costs more to make tight: the reciprocal-power cost model of tolerance
allocation) subject to ``W(h) ≤ limit``, solved with ``optax.adam`` on ``y = log h`` inside an
augmented Lagrangian (one multiplier per constraint row or corner). With thousands of rows that
comes near the optimum but not onto it, so a max-type box, a convex program in ``h``, is then
converged by the log-barrier method (Newton steps of size ``P``, to a duality gap of 1e-9); the
result is then scaled onto the limit exactly. Components the metric does not feel are capped at ``h_max``
(5 mm / 5 mrad by default: the range in which the linear model is trusted) and reported as
*unconstrained*.

The linear model of a study's runs themselves, from which every linear response of the same study
is read, is :class:`jaxbelt.design.linearisation.LinearDeviation`.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .metrics import aggregate

H_MAX = 5.0  # mm / mrad: widest half-width reported (linear range of the model)
ENUMERATE_MAX_P = 16


@dataclasses.dataclass(frozen=True)
class LinearResponse:
    """``r(θ) ≈ r0 + J θ`` with the metric's aggregate ``kind`` (``"max"`` | ``"rms"``)."""

    r0: np.ndarray
    J: np.ndarray
    kind: str

    def metric(self, theta):
        return float(aggregate(self.kind, jnp.asarray(self.r0 + self.J @ np.asarray(theta))))


# ----------------------------------------------------------------------------- worst case


def _rms_corners(lin: LinearResponse, h) -> np.ndarray:
    """Candidate sign vectors (m, P) for the RMS worst case (all corners when P is small)."""
    P = lin.J.shape[1]
    if P <= ENUMERATE_MAX_P:
        return np.array(list(itertools.product((-1.0, 1.0), repeat=P)))
    Jh = lin.J * h
    rows = np.where(np.where(lin.r0 >= 0, 1.0, -1.0)[:, None] * Jh >= 0, 1.0, -1.0)
    _, _, vt = np.linalg.svd(Jh, full_matrices=False)
    cands = np.concatenate([rows, np.sign(vt[:4] + 1e-300), -np.sign(vt[:4] + 1e-300)])
    best = cands[np.argmax(np.linalg.norm(lin.r0 + (cands * h) @ lin.J.T, axis=1))]
    for _ in range(2 * P):  # single-flip improvement of the best candidate
        flips = best[None, :] * np.where(np.eye(P) > 0, -1.0, 1.0)
        vals = np.linalg.norm(lin.r0 + (flips * h) @ lin.J.T, axis=1)
        if vals.max() <= np.linalg.norm(lin.r0 + (best * h) @ lin.J.T):
            break
        best = flips[np.argmax(vals)]
    return np.unique(np.concatenate([cands, best[None]]), axis=0)


def worst_corners(lin: LinearResponse, h, k: int = 4):
    """The ``k`` distinct box corners with the largest linear-model metric, worst first.

    **Returns:** ``(signs (m, P), values (m,))``: ``θ = signs * h``."""
    h = np.asarray(h, float)
    if lin.kind == "max":
        side = np.where(lin.r0 >= 0, 1.0, -1.0)[:, None]  # with r0_i = 0 either side is worst
        signs = np.where(side * lin.J >= 0, 1.0, -1.0)
        vals = np.abs(lin.r0) + np.abs(lin.J) @ h
    else:
        signs = _rms_corners(lin, h)
        vals = np.sqrt(np.mean((lin.r0 + (signs * h) @ lin.J.T) ** 2, axis=1))
    order = np.argsort(-vals)
    _, first = np.unique(signs[order], axis=0, return_index=True)
    keep = order[np.sort(first)][:k]
    return signs[keep], vals[keep]


def worst_case(lin: LinearResponse, h) -> float:
    """Largest linear-model metric over the box ``|θ| ≤ h``."""
    return float(worst_corners(lin, h, 1)[1][0])


# ----------------------------------------------------------------------------- optimisation


def _constraint_data(lin: LinearResponse, h):
    """Rows of the constraint ``g_j(h) ≤ limit``: max-type ``|r0_i| + |J_i|·h`` (one per response
    row); RMS ``‖r0 + J (s_j ∘ h)‖/√n`` for the candidate corners ``s_j``."""
    if lin.kind == "max":
        return np.abs(lin.r0), np.abs(lin.J), None
    return lin.r0, lin.J, _rms_corners(lin, h)


def _g(lin_kind, a, B, S, h):
    if lin_kind == "max":
        return a + B @ h
    return jnp.sqrt(jnp.mean((a[None, :] + (S * h) @ B.T) ** 2, axis=1))


def optimise_box(lin: LinearResponse, limit: float, weights=None, h_max: float = H_MAX,
                 outer: int = 25, inner: int = 400, learning_rate: float = 0.05) -> np.ndarray:
    """Half-widths (P,) maximising ``Σ w_k log h_k`` subject to the linear worst case ≤ ``limit``
    (augmented Lagrangian, ``optax.adam`` on ``log h``, then scaled exactly onto the limit). The
    constraint rows are arguments of one compiled program (:func:`_augmented_lagrangian`), which
    every call of the same shapes reuses. A max-type box is then converged by the log-barrier
    method (:func:`_barrier_newton`), the Lagrangian's result (10 × 100 steps at most) its start."""
    P = lin.J.shape[1]
    w = np.ones(P) if weights is None else np.asarray(weights, float)
    if np.any(~np.isfinite(w)) or np.any(w <= 0):
        raise ValueError(f"weights = {w.tolist()}: must be positive and finite")
    floor = float(aggregate(lin.kind, jnp.asarray(lin.r0)))
    if not floor < limit:
        raise ValueError(f"limit = {limit} µm: the scene's own misalignment already gives {floor:.4g} µm; "
                         "no tolerance box fits")
    felt = np.any(lin.J != 0, axis=0)
    scale = np.maximum(np.abs(lin.J).max(axis=0), 1e-300)
    h0 = np.where(felt, (limit - floor) / (P * scale), h_max)
    h0 = np.minimum(h0, h_max)
    a, B, S = _constraint_data(lin, h0)
    wn = jnp.asarray(w / w.sum())
    y0 = jnp.log(jnp.asarray(h0))  # h0 ≤ h_max
    if lin.kind == "max":  # the Lagrangian only starts the barrier method there (:func:`_barrier_newton`)
        outer, inner = min(outer, 10), min(inner, 100)
    settings = dict(kind=lin.kind, outer=outer, inner=inner, learning_rate=learning_rate)

    y = _augmented_lagrangian(jnp.asarray(a), jnp.asarray(B), None if S is None else jnp.asarray(S), wn, y0,
                              float(np.log(h_max)), float(limit), **settings)
    h = np.exp(np.minimum(np.asarray(y), np.log(h_max)))
    if lin.kind == "max" and felt.any():
        h = _barrier_newton(a, B, w, limit, h_max, felt, h)
    return _scale_onto_limit(lin, h, limit, h_max, felt)


def _barrier_newton(a, B, w, limit, h_max, felt, h_start, gap: float = 1e-9, max_newton: int = 60):
    """The max-type box to convergence: ``max Σ w_k log h_k`` s.t. ``a + B h ≤ limit`` and
    ``h ≤ h_max`` is a convex program in ``h`` (concave objective, linear constraints), solved by
    the log-barrier method (Boyd & Vandenberghe §11.3): Newton's method with a feasible
    backtracking line search on ``t f(h) + φ(h)`` for ``t`` ×10 until the duality gap ``m/t`` is
    under ``gap`` relative to the objective. The augmented Lagrangian's result is the start: with
    thousands of rows it comes near the optimum but not onto it (its box depends on the rounding
    of the sums), and the Newton steps, of size ``P``, settle it."""
    k = np.flatnonzero(felt)
    Bk, wk = B[:, k], w[k]
    c = limit - a - B[:, ~felt] @ h_start[~felt]  # unfelt components sit at their cap (no row feels them)
    h = np.minimum(np.asarray(h_start, float)[k], 0.99 * h_max)
    h = h * min(1.0, 0.9 * float(np.min(c / np.maximum(Bk @ h, 1e-300))))  # strictly inside
    m = len(c) + 2 * len(k)

    def phi(h, t):
        s_, u_ = c - Bk @ h, h_max - h
        if np.any(h <= 0) or np.any(s_ <= 0) or np.any(u_ <= 0):
            return np.inf
        return -t * np.sum(wk * np.log(h)) - np.sum(np.log(s_)) - np.sum(np.log(u_))

    t = m / max(abs(np.sum(wk * np.log(h))), 1.0)
    while True:
        for _ in range(max_newton):
            s_, u_ = c - Bk @ h, h_max - h
            grad = -t * wk / h + Bk.T @ (1.0 / s_) + 1.0 / u_
            hess = np.diag(t * wk / h**2 + 1.0 / u_**2) + (Bk / s_[:, None] ** 2).T @ Bk
            dh = -np.linalg.solve(hess, grad)
            decrement = -grad @ dh
            if decrement / 2 <= 1e-12:
                break
            step, f0 = 1.0, phi(h, t)
            while phi(h + step * dh, t) > f0 - 0.25 * step * decrement and step > 1e-12:
                step *= 0.5
            h = h + step * dh
        if m / t <= gap * max(abs(np.sum(wk * np.log(h))), 1.0):
            break
        t *= 10.0
    out = np.asarray(h_start, float).copy()
    out[k] = h
    return out


@functools.partial(jax.jit, static_argnames=("kind", "outer", "inner", "learning_rate"))
def _augmented_lagrangian(a, B, S, wn, y0, y_max, limit, *, kind, outer, inner, learning_rate):
    """``log h`` of :func:`optimise_box`'s augmented Lagrangian: ``outer`` multiplier updates
    (penalty ×2 each, from 10 to at most 1e5) of ``inner`` projected Adam steps each."""
    opt = optax.adam(learning_rate)

    def lagrangian(y, lam, rho):
        c = _g(kind, a, B, S, jnp.exp(y)) / limit - 1.0
        return -jnp.sum(wn * y) + jnp.sum(jnp.maximum(0.0, lam + rho * c) ** 2 - lam**2) / (2 * rho), c

    def solve_inner(y, lam, rho):
        def body(carry, _):
            y, st = carry
            g = jax.grad(lambda y_: lagrangian(y_, lam, rho)[0])(y)
            upd, st = opt.update(g, st, y)
            return (jnp.minimum(optax.apply_updates(y, upd), y_max), st), None  # projected onto h ≤ h_max

        (y, _), _ = jax.lax.scan(body, (y, opt.init(y)), None, length=inner)
        return y, lagrangian(y, lam, rho)[1]

    def outer_body(carry, _):
        y, lam, rho = carry
        y, c = solve_inner(y, lam, rho)
        return (y, jnp.maximum(0.0, lam + rho * c), jnp.minimum(rho * 2.0, 1e5)), None

    n_c = a.shape[0] if S is None else S.shape[0]
    init = (y0, jnp.zeros(n_c, y0.dtype), jnp.asarray(10.0, y0.dtype))
    (y, _, _), _ = jax.lax.scan(outer_body, init, None, length=outer)
    return y


def _scale_onto_limit(lin, h, limit, h_max, felt):
    """Scale the felt components by one factor so the linear worst case equals ``limit``
    (bisection; max-type worst cases evaluated in closed form, ``max_i |r0_i| + |J_i|·h``)."""
    if lin.kind == "max":
        a, B, _ = _constraint_data(lin, h)

        def W(x):
            return float(np.max(_g("max", a, B, None, x)))
    else:
        def W(x):
            return worst_case(lin, x)

    lo, hi = 0.0, 1.0
    while W(np.where(felt, np.minimum(hi * h, h_max), h)) < limit and hi < 1e6:
        lo, hi = hi, hi * 2
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if W(np.where(felt, np.minimum(mid * h, h_max), h)) <= limit:
            lo = mid
        else:
            hi = mid
    return np.where(felt, np.minimum(lo * h, h_max), h)


# ----------------------------------------------------------------------------- stack-up and shares


@dataclasses.dataclass(frozen=True)
class Stackup:
    """A statistical stack-up (:func:`rss_stackup`). **Fields:** ``sigma_um`` (n_r,) the standard
    deviation of every response row, µm; ``three_sigma_um`` the metric of ``|r0| + 3 σ_r``, µm."""

    sigma_um: np.ndarray
    three_sigma_um: float


def rss_stackup(lin: LinearResponse, sigma) -> Stackup:
    """Statistical stack-up: per response row ``σ_r = sqrt(Σ_k J_ik² σ_k²)`` for independent
    components with standard deviations ``sigma`` (P,), and the metric of ``|r0| + 3 σ_r``."""
    sigma = np.asarray(sigma, float)
    s_r = np.sqrt((lin.J**2) @ sigma**2)
    return Stackup(sigma_um=s_r, three_sigma_um=float(aggregate(lin.kind, jnp.asarray(np.abs(lin.r0) + 3 * s_r))))
