"""When to trust a reduced model: an a-posteriori error estimate of its tracer error.

**What is estimated.** A reduced model produces states ``z_0 … z_n`` (scaled first-order states,
lifted from its coordinates: ``z_k = V ξ_k``); the full model from the same start would produce
``z*_k``. The estimate is of the quantity ``jaxbelt reduce`` reports as the error: the tracer RMSE
over the predicted steps and tracers — ``rmse_um = (mean over steps k and tracers i of
(C(z*_k - z_k))_i²)^½`` with ``C`` the longitudinal tracer operator (for DMD on pre-transport
snapshots, the pre-transport tracers ``tracer_u_solved``, as ``reduce`` compares), in µm — and its
maximum over time, ``max_rmse_over_time_um``. :func:`error_rom` returns the estimated signed
tracer error at every step, so any norm of it can be taken.

**Error ROM** (:func:`error_rom`). The one-step residual ``δ_k = F(z_k) - z_{k+1}`` (``F`` one
full-order step: solve + transport) needs no reference run, and the error ``e_k = z*_k - z_k``
obeys ``e_{k+1} = F(z*_k) - F(z_k) + δ_k ≈ J e_k + δ_k`` with ``J`` the step's Jacobian at
``z_0``: the step is affine up to the shift transport's bilinearity and, in 2D, the tilts' lever
arm. With every residual and the exact ``J`` this linear model reproduces the true tracer error to
a few per cent, but it costs one full step per step. Three approximations make it cheap:

1. *Residuals averaged over windows.* For an affine step the mean of the residuals over a window
   of ``stride`` steps equals ``F(mean z_k) - mean z_{k+1}``: one full step per window, exact up
   to the bilinearity, and — unlike the residual at every ``stride``-th step — not aliased by the
   residual's oscillations at the belt's frequencies. The first ``dense`` steps (the start-up
   transient) are windows of their own, and so is every step of a window whose mean residual
   differs from a neighbour's by more than ``refine_rtol`` of the larger (norms below
   ``refine_floor`` of the largest count as that floor): driving the propagation with a window's
   mean at each of its steps is right where the residual is steady or oscillates quickly, not
   where it still changes from one window to the next: on the start-up of DMDc over the
   15-component box predicting ``three-roller-t72`` (steps 10-50) windows of 10 made the
   estimate 6x the true error at step 10 and its RMSE 2.35x; evaluated step by step there, 1.3x
   and 1.57x.
2. *The Jacobian in a subspace* ``W``: the reduced model's own basis, the directions of the window
   residuals and of the initial error outside it (singular values above ``enrich_rtol`` of their
   norm, at most ``max_enrich``: the residual carries what the basis cannot represent, e.g. a
   misalignment direction no training run varied), ``krylov`` images of those under ``J``
   (where that error goes next), and — where the residual has settled (over the last quarter of
   the steps its spread about its mean is at most half the mean) — the *quasi-static response*
   ``x = (I - J)⁻¹ r̄`` to the settled mean residual ``r̄``: the level the error settles to, by
   GMRES on Jacobian-vector products to ``qs_rtol`` (at most ``qs_max_iter`` iterations; the
   iterate at the cap otherwise). A few Krylov images cannot represent it when the step's slowest
   modes decay over tens of steps (|λ| ≈ 0.95 in 2D): without it the settled error of that DMDc
   case came out 2.0x the true one (with it 1.1x; every residual through the exact ``J``: 0.95x),
   its RMSE 1.57x (with it 1.32x; exact ``J``: 0.99x), and the other box case's 0.71x (1.13x;
   1.13x). ``A = Wᵀ J W`` from one Jacobian-vector product per column. Eigenvalues of ``A``
   outside the unit circle (spurious growth of the Galerkin projection of the non-normal step;
   the full step is non-expansive) are pulled onto it.
3. ``ê_{k+1} = A ê_k + Wᵀ δ̄_{w(k)}``, ``ê_0 = Wᵀ(z*_0 - z_0)``, a ``lax.scan`` of ``dim W``-sized
   products; the estimated tracer error is ``C W ê_k``.

**Online cost**, in full-step equivalents: one full step per window (``dense + (n - dense) /
stride + 1``, plus one per step of the refined windows and one per window they replace; batched,
they are independent) plus ``dim W`` + the quasi-static iterations Jacobian-vector products (each
about one full step), plus ``O(n · dim W²)`` reduced work; ``cost`` in the result counts them.
Measured (``results/rom_indicator.json``): 151-257 for 1000-1500 predicted 2D steps at the
default stride 10 (12-25 % of the full run it replaces), 596 for 5000 (12 %), 171-210 for 600
steps of the box cases, whose start-up is a larger share.

**Safety factor and snapshot rule**: :mod:`jaxbelt.rom.calibration` (the estimate scaled by
what the same fit does on training data; the number of training steps decided from the data).

**Triangle-inequality indicator** (:func:`residual_indicator`, the earlier one, kept for
comparison): ``Σ_k stride · ‖C δ_k‖`` over every ``stride``-th residual. It ignores that the
residuals' effects cancel and decay, and errs high by 10-700x (``results/rom_indicator.json``,
ablation).
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from ..integrators import AbstractIntegrator, make_solver
from .full_steps import apply_steps, full_step_map, in_chunks, jvp_columns, jvp_one, run_data_at_start
from .snapshots import tracer_operator


@dataclasses.dataclass(frozen=True)
class ResidualIndicator:
    """:func:`residual_indicator`'s result: ``step`` (k,) the sampled steps; ``residual_um`` (k,)
    the rms over tracers of ``C δ_k`` there, µm; ``estimate_um`` (k,) the accumulated estimate
    of the tracer error ``Σ stride·|C δ|`` up to each sampled step, µm."""

    step: np.ndarray
    residual_um: jax.Array
    estimate_um: jax.Array


def residual_indicator(model, states, dt, stride: int = 10, solver: AbstractIntegrator | None = None,
                       order: str = "post") -> ResidualIndicator:
    """Residual-based error indicator of a reduced trajectory.

    **Arguments:** ``states`` (n+1, 2N): lifted scaled first-order states ``z_0 … z_n`` of the
    reduced model (``ReducedStep.fields``, ``DMDModel.predict``, …) with time step ``dt``;
    ``stride``: evaluate every ``stride``-th step; ``order``: see :func:`~jaxbelt.rom.full_steps.full_step_map`.
    """
    states = jnp.asarray(states)
    F = jax.jit(jax.vmap(full_step_map(model, dt, solver, order)))
    idx = np.arange(0, states.shape[0] - 1, stride)
    C = tracer_operator(model)
    N = model.n_unknowns
    delta = F(states[idx]) - states[idx + 1]
    res = jnp.sqrt(jnp.mean((delta[:, :N] @ C.T) ** 2, axis=1)) * 1e6
    return ResidualIndicator(step=idx, residual_um=res, estimate_um=jnp.cumsum(res) * stride)


# --------------------------------------------------------------------------- the error ROM


def warm_error_rom(model, dt, solver: AbstractIntegrator | None = None, order: str = "post",
                   options: "ErrorRomOptions | None" = None):
    """Compile, without running them, the full-order programs of :func:`error_rom` for
    ``model``'s shapes: the start data, the batched full steps and the Jacobian-vector products
    (lowered on zero arrays of the shapes they take; :func:`error_rom`'s calls then find them).
    Another configuration of the same mesh reuses them. Nothing executes, so a caller with other
    work to do first runs this in a background thread and overlaps the compilation with that work
    (two XLA:CPU executions at once can wedge its thread pool)."""
    solver = make_solver() if solver is None else solver
    chunk = (ErrorRomOptions() if options is None else options).chunk
    dt = jnp.asarray(dt, model.ell.dtype)
    run_data_at_start.lower(model, solver, dt).compile()
    run_data = jax.tree.map(lambda x: np.zeros(x.shape, x.dtype) if isinstance(x, jax.ShapeDtypeStruct) else x,
                            eqx.filter_eval_shape(run_data_at_start, model, solver, dt))
    n = 2 * model.n_unknowns
    z, dtype = np.zeros(n, model.ell.dtype), model.ell.dtype
    apply_steps.lower(model, dt, solver, order, 1, np.zeros((chunk, n), dtype), run_data).compile()
    jvp_columns.lower(model, dt, solver, order, 1, z, np.zeros((n, chunk), dtype), run_data).compile()
    jvp_one.lower(model, dt, solver, order, 1, z, z, run_data).compile()


def _remainder_svd(W, X):
    """``‖X‖₂`` and the SVD of ``X`` minus its projection on ``span(W)`` (twice Gram-Schmidt), in
    NumPy: ``X``'s column count changes from call to call, and a compiled program per shape
    costs more than the LAPACK calls themselves."""
    W, X = np.asarray(W), np.asarray(X)
    scale = float(np.linalg.norm(X, 2))
    for _ in range(2):
        X = X - W @ (W.T @ X)
    U, s, _ = np.linalg.svd(X, full_matrices=False)
    return scale, U, s


def _new_directions(W, X, rtol, max_new):
    """Orthonormal directions of ``X`` (2N, m) outside ``span(W)``: left singular vectors of the
    remainder (twice Gram-Schmidt) with singular value above ``rtol · ‖X‖₂``, at most ``max_new``
    (a NumPy array)."""
    if X.shape[1] == 0 or max_new <= 0:
        return np.zeros((W.shape[0], 0), W.dtype)
    scale, U, s = _remainder_svd(W, X)
    scale = float(scale)
    keep = int(min(max_new, np.sum(np.asarray(s) > rtol * scale))) if scale > 0 else 0
    return np.asarray(U)[:, :keep]


def _stabilised(A):
    """``A`` with every eigenvalue of modulus above one pulled onto the unit circle. The full
    step is non-expansive (Backward Euler damps, the transport is a relabelling; its tracer
    impulse response ‖C Jᵐ‖ stays bounded), but a Galerkin projection of the non-normal step
    can have spurious growing modes — they would turn the estimate into a blow-up."""
    A = np.asarray(A)
    lam, P = np.linalg.eig(A)
    rho = float(np.max(np.abs(lam))) if lam.size else 0.0
    if rho <= 1.0 + 1e-9:
        return jnp.asarray(A), rho
    lam = lam / np.maximum(1.0, np.abs(lam))
    return jnp.asarray(np.real(P @ np.diag(lam) @ np.linalg.inv(P))), rho


def _quasi_static_response(J, r, rtol: float, max_iter: int):
    """``x ≈ (I - J)⁻¹ r`` by GMRES (Arnoldi with twice Gram-Schmidt, NumPy, one Jacobian-vector
    product per iteration) to ``‖(I - J)x - r‖ ≤ rtol ‖r‖``; returns ``(x, iterations)``."""
    r = np.asarray(r, float)
    beta = float(np.linalg.norm(r))
    if beta == 0.0 or not np.isfinite(beta) or max_iter < 1:
        return np.zeros_like(r), 0
    Q = [r / beta]
    H = np.zeros((max_iter + 1, max_iter))
    y = np.zeros(0)
    for j in range(max_iter):
        w = Q[j] - np.asarray(J(jnp.asarray(Q[j])))  # (I - J) q_j
        Qm = np.stack(Q, axis=1)
        for _ in range(2):
            c = Qm.T @ w
            w = w - Qm @ c
            H[: j + 1, j] += c
        H[j + 1, j] = np.linalg.norm(w)
        e1 = np.zeros(j + 2)
        e1[0] = beta
        y, *_ = np.linalg.lstsq(H[: j + 2, : j + 1], e1, rcond=None)
        res = np.linalg.norm(H[: j + 2, : j + 1] @ y - e1)
        if res <= rtol * beta or H[j + 1, j] <= 1e-14 * beta:
            return np.stack(Q, axis=1) @ y, j + 1
        Q.append(w / H[j + 1, j])
    return np.stack(Q[: len(y)], axis=1) @ y, max_iter


def _split_changing_windows(starts, n: int, D, rtol: float, floor: float) -> np.ndarray:
    """Window starts with every window whose mean residual differs from a neighbour's by more than
    ``rtol`` of the larger (norms below ``floor`` count as ``floor``) cut into single steps."""
    norms = np.maximum(np.linalg.norm(D, axis=1), floor)
    jump = np.linalg.norm(np.diff(D, axis=0), axis=1) / np.maximum(norms[1:], norms[:-1])
    changing = np.zeros(len(starts), bool)
    changing[:-1] |= jump > rtol
    changing[1:] |= jump > rtol
    edges = np.concatenate([starts, [n]])
    singles = [np.arange(a, b) for a, b, c in zip(edges[:-1], edges[1:], changing) if c and b - a > 1]
    return np.unique(np.concatenate([starts, *singles]).astype(int))


@jax.jit
def _propagate(A, drive, window, out, e0):
    """``e_{k+1} = A e_k + drive[window[k]]`` from ``e0``, observed: ``out @ e_k`` for k = 1 … n."""

    def body(e, w):
        e = A @ e + drive[w]
        return e, out @ e

    return lax.scan(body, e0, window)[1]


@dataclasses.dataclass(frozen=True)
class ErrorRomOptions:
    """Tuning of :func:`error_rom` (the module docstring explains each piece; the defaults are the
    measured ones).

    **Fields:** ``dense``: the first ``dense`` steps are windows of their own (the start-up);
    ``sampling``: ``"window"`` (the window mean residual) or ``"point"`` (the residual at each
    window's first step — aliased, for comparison only); ``refine_rtol``/``refine_floor``: windows
    whose mean residual changes by more than ``refine_rtol`` from a neighbour's are evaluated step
    by step (``refine_rtol=None``: never); ``enrich_rtol``/``max_enrich``/``krylov``: the
    enrichment of the subspace; ``quasi_static``/``qs_rtol``/``qs_max_iter``: the quasi-static
    response of a settled residual in it; ``chunk``: full steps and Jacobian-vector products per
    compiled batch.
    """

    dense: int = 10
    sampling: str = "window"
    refine_rtol: float | None = 0.5
    refine_floor: float = 1e-2
    enrich_rtol: float = 1e-3
    max_enrich: int = 20
    krylov: int = 1
    quasi_static: bool = True
    qs_rtol: float = 1e-2
    qs_max_iter: int = 40
    chunk: int = 16

    def __post_init__(self):
        if self.sampling not in ("window", "point"):
            raise ValueError("sampling must be 'window' or 'point'")

    def replace(self, **changes) -> "ErrorRomOptions":
        return dataclasses.replace(self, **changes)


@dataclasses.dataclass(frozen=True)
class EstimateCost:
    """What an :func:`error_rom` estimate spent: ``full_steps`` (window residuals), ``jvps``
    (Jacobian-vector products: subspace columns and quasi-static iterations), ``windows``,
    ``quasi_static_iterations``, ``full_step_equivalents`` (``full_steps + jvps``, each product
    about one full step)."""

    full_steps: int
    jvps: int
    windows: int
    quasi_static_iterations: int
    full_step_equivalents: int


class BasisTrajectory(NamedTuple):
    """A reduced prediction as coordinates in an orthonormal basis of full states, the form
    :func:`error_rom` reads: the full state after step ``k`` is ``basis @ coords[k]``.

    **Fields:** ``basis`` (2N, b) orthonormal columns; ``coords`` (n+1, b), row 0 the start;
    ``z_true0`` (2N,) the full model's state at step 0 (``None``: the start is exact).
    """

    basis: jax.Array
    coords: jax.Array
    z_true0: jax.Array | None = None


@dataclasses.dataclass(frozen=True)
class ErrorEstimate:
    """:func:`error_rom`'s estimate of a reduced trajectory's observation error.

    **Fields:** ``error`` (n, o) the estimated signed observation error after each step 1 … n, m;
    ``error_um`` (n,) its rms over the observed tracers, µm; ``rmse_um`` its rms over the steps
    too, µm; ``max_um`` its maximum over the steps, µm; ``cost`` (:class:`EstimateCost`); ``dim`` the
    subspace size; ``rho`` the largest |λ| of the projected Jacobian before stabilisation;
    ``settled`` whether the late residual had settled (the quasi-static response was used).
    """

    error: jax.Array
    error_um: jax.Array
    rmse_um: float
    max_um: float
    cost: EstimateCost
    dim: int
    rho: float
    settled: bool


def error_rom(model, basis, coords, dt, z_true0=None, *, stride: int = 10, order: str = "post", steps: int = 1,
              solver: AbstractIntegrator | None = None, observe=None,
              options: ErrorRomOptions = ErrorRomOptions()) -> ErrorEstimate:
    """Error ROM: estimate of the tracer error of a reduced trajectory from its full-order residuals
    propagated through the full step's Jacobian in a residual-enriched subspace.

    **Arguments:** the reduced trajectory as full states ``z_k = basis @ coords[k]``, ``k = 0 … n``
    (``basis`` (2N, b) orthonormal, ``coords`` (n+1, b)); ``dt`` the time step of the full steps
    (s); ``z_true0`` the full model's state at step 0 (its difference from ``z_0`` is the initial
    error; ``None``: zero); ``model`` the configuration predicted; ``order``/``steps``: the
    reduced model's step is ``steps`` full steps in ``order`` (:func:`~jaxbelt.rom.full_steps.full_step_map`) of
    ``solver`` (default :func:`jaxbelt.make_solver`'s); ``observe`` (o, N) what the error is
    measured on (default the longitudinal tracers,
    :func:`~jaxbelt.rom.snapshots.tracer_operator`); ``stride``: residual windows of ``stride``
    steps; ``options``: the remaining tuning (:class:`ErrorRomOptions`).

    See the module docstring for the method and its accuracy.
    """
    if order not in ("post", "pre"):
        raise ValueError("order must be 'post' or 'pre'")
    # the algebra around the full steps runs in NumPy: these arrays change shape with every call,
    # and op by op each JAX primitive of a new shape is a compile (the full steps are compiled)
    basis, coords = np.asarray(basis), np.asarray(coords)
    n = int(coords.shape[0]) - 1
    if n < 1:
        raise ValueError("error_rom: need at least one reduced step")
    stride, steps = max(int(stride), 1), max(int(steps), 1)
    solver = make_solver() if solver is None else solver
    dt = jnp.asarray(dt, basis.dtype)
    obs = np.asarray(tracer_operator(model) if observe is None else observe)
    obs = np.concatenate([obs, np.zeros_like(obs)], axis=1)

    run_data = run_data_at_start(model, solver, dt)

    def F(Z):
        return in_chunks(lambda X: apply_steps(model, dt, solver, order, steps, X, run_data), Z, options.chunk, 0)

    starts, D, evaluated = _window_residuals(F, basis, coords, stride, options)
    edges = np.concatenate([starts, [n]])
    z0 = basis @ coords[0]
    e0 = np.zeros_like(z0) if z_true0 is None else np.asarray(z_true0) - z0
    z0_j = jnp.asarray(z0)

    def J(V):
        return in_chunks(lambda X: jvp_columns(model, dt, solver, order, steps, z0_j, X, run_data), V,
                        options.chunk, 1)

    def Jv(v):
        return jvp_one(model, dt, solver, order, steps, z0_j, v, run_data)

    W, JW, qs_iter, settled = _error_subspace(J, Jv, basis, D, e0, edges, options)
    A, rho = _stabilised(W.T @ JW)
    window = np.repeat(np.arange(len(starts)), np.diff(edges))
    err = np.asarray(_propagate(A, D @ W, window, obs @ W, W.T @ e0))
    err_um = np.sqrt(np.mean(err**2, axis=1)) * 1e6
    full_steps, jvps = int((evaluated + 1) * steps), int((W.shape[1] + qs_iter) * steps)
    cost = EstimateCost(full_steps=full_steps, jvps=jvps, windows=int(len(starts)),
                        quasi_static_iterations=int(qs_iter), full_step_equivalents=full_steps + jvps)
    return ErrorEstimate(error=jnp.asarray(err), error_um=jnp.asarray(err_um),
                         rmse_um=float(np.sqrt(np.mean(err_um**2))), max_um=float(np.max(err_um)), cost=cost,
                         dim=int(W.shape[1]), rho=rho, settled=settled)


def _window_residuals(F, basis, coords, stride: int, options: ErrorRomOptions):
    """``(starts, D, evaluated)``: the residual windows' first steps, their mean residuals
    ``F(mean z_k) - mean z_{k+1}`` (windows, 2N) and the number of windows evaluated.

    Every step of the first ``dense`` is a window (the start-up transient), then ``stride`` steps
    each; where the mean residual still changes from one window to the next (a transient), the
    window mean misrepresents it and those windows are evaluated step by step."""
    n = int(coords.shape[0]) - 1
    cum = np.concatenate([np.zeros((1, coords.shape[1])), np.cumsum(coords, axis=0)])

    def residuals(starts, ends):
        width = (ends - starts)[:, None]
        mean_now = (cum[ends] - cum[starts]) / width
        mean_next = (cum[ends + 1] - cum[starts + 1]) / width
        if options.sampling == "point":
            mean_now, mean_next = coords[starts], coords[starts + 1]
        return F(mean_now @ basis.T) - mean_next @ basis.T  # (windows, 2N) window-mean residuals

    def ends_of(starts):
        return np.concatenate([starts[1:], [n]])

    dense = max(int(options.dense), 0)
    starts = np.unique(np.concatenate([np.arange(min(dense, n)), np.arange(0, n, stride)]))
    D = residuals(starts, ends_of(starts))
    evaluated = len(starts)
    if options.refine_rtol is not None and options.sampling == "window" and stride > 1:
        floor = options.refine_floor * float(np.max(np.linalg.norm(D, axis=1)))
        fine = _split_changing_windows(starts, n, D, options.refine_rtol, floor)
        if len(fine) > len(starts):
            # a window of `fine` kept whole has its start and its end among the old ones
            at = np.minimum(np.searchsorted(starts, fine), len(starts) - 1)
            kept = (starts[at] == fine) & (ends_of(starts)[at] == ends_of(fine))
            D_fine = np.empty((len(fine), D.shape[1]))
            D_fine[kept] = D[at[kept]]
            D_fine[~kept] = residuals(fine[~kept], ends_of(fine)[~kept])
            starts, D = fine, D_fine
            evaluated += int(np.sum(~kept))
    return starts, D, evaluated


def _error_subspace(J, Jv, basis, D, e0, edges, options: ErrorRomOptions):
    """``(W, J W, quasi-static iterations, settled)``: the subspace of the error ROM — the model's
    basis, the residual (and initial error) directions outside it, ``krylov`` images of those
    under the step's Jacobian ``J`` and, where the late residual has settled, its quasi-static
    response."""
    W = np.linalg.qr(basis)[0]
    JW = [J(W)]
    blk = _new_directions(W, np.concatenate([D.T, e0[:, None]], axis=1), options.enrich_rtol, options.max_enrich)
    Wcols = [W]
    for level in range(options.krylov + 1):
        if blk.shape[1] == 0:
            break
        Wcols.append(blk)
        Jb = J(blk)
        JW.append(Jb)
        if level == options.krylov:
            break
        blk = _new_directions(np.concatenate(Wcols, axis=1), Jb, 1e-8, blk.shape[1])
    W, JW = np.concatenate(Wcols, axis=1), np.concatenate(JW, axis=1)
    qs_iter = 0
    # the quasi-static response to a settled residual: the level the error settles to once the
    # residual stays constant, (I - J)⁻¹ r, which a short Krylov space of J approximates poorly
    # (|λ| ~ 0.95 in 2D); only where the residual over the last quarter has settled (its spread
    # about its mean is at most half the mean: an oscillating residual has no such level)
    n = int(edges[-1])
    width = np.diff(edges)[:, None]
    late = np.flatnonzero(edges[:-1] >= n - max(n // 4, 1))
    w_late = width[late] / np.sum(width[late])
    r_late = np.sum(D[late] * w_late, axis=0)
    spread = float(np.sqrt(np.sum(w_late[:, 0] * np.sum((D[late] - r_late) ** 2, axis=1))))
    settled = bool(late.size) and spread <= 0.5 * float(np.linalg.norm(r_late))
    if options.quasi_static and settled:
        x, qs_iter = _quasi_static_response(Jv, r_late, options.qs_rtol, options.qs_max_iter)
        extra = _new_directions(W, x[:, None], 1e-8, 1) if np.any(x) else np.zeros((W.shape[0], 0))
        if extra.shape[1]:
            W = np.concatenate([W, extra], axis=1)
            JW = np.concatenate([JW, J(extra)], axis=1)
    return W, JW, qs_iter, settled
