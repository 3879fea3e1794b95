"""Exact dynamic mode decomposition (Tu et al.; the source's eq. 5.14–5.33) as pure ``jnp``.

From snapshot pairs ``X = [x_0 … x_{m-1}]``, ``X' = [x_1 … x_m]`` (columns; several trajectories
are stacked pairwise, eq. 6.12–6.13): ``X ≈ U_r Σ_r V_rᴴ`` (rank ``r``),
``Ã = U_rᴴ X' V_r Σ_r⁻¹``, ``Ã W = W Λ``, modes ``Φ = X' V_r Σ_r⁻¹ W`` (exact DMD, eq. 5.27).
A prediction from any start snapshot ``x_{k₀}`` uses amplitudes ``b = Φ⁺ x_{k₀}``
(eq. 5.29, 5.32) and ``x_{k₀+k} ≈ Re(Φ Λᵏ b)``. Modes with ``|λ| > 1`` can be discarded and the
rest ranked by ``|λ|`` or by the norm of the scaled mode ``‖φ_i b_i‖`` (§6.4.1, §7.4.1).

The fit returns a frozen :class:`DMDModel`; nothing mutates, so ``jit``/``grad`` go through the
fit and the prediction (eigenvector derivatives assume distinct eigenvalues).
"""

from __future__ import annotations

import functools
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..timeloop import RunOptions
from .error_estimate import BasisTrajectory
from .reduced_model import AbstractReducedModel, AbstractReduction, Prediction, Spectra, TrainingRuns
from .snapshots import collect_first_order, tracer_operator


class DMDModel(eqx.Module):
    """A fitted DMD: ``eigs`` (r,) complex, ``modes`` (N, r) complex."""

    eigs: jax.Array
    modes: jax.Array

    def amplitudes(self, x_start):
        """Least-squares amplitudes ``b = Φ⁺ x_start`` (eq. 5.29)."""
        return jnp.linalg.lstsq(self.modes, x_start.astype(self.modes.dtype))[0]

    def select(self, keep: jax.Array) -> "DMDModel":
        """The model restricted to the modes where ``keep`` (a boolean mask or index array)."""
        try:  # concrete arrays: indexed in NumPy (op by op, each new shape is a compile in JAX)
            e, m, k = np.asarray(self.eigs), np.asarray(self.modes), np.asarray(keep)
        except (jax.errors.TracerArrayConversionError, jax.errors.ConcretizationTypeError):
            return DMDModel(self.eigs[keep], self.modes[:, keep])
        return DMDModel(jnp.asarray(e[k]), jnp.asarray(m[:, k]))

    def stable(self, tol: float = 1e-5) -> "DMDModel":
        """Discard modes with ``|λ| > 1 + tol`` (outside Python control flow: shapes change).

        The default is not round-off: the mode carrying the static offset sits at ``λ ≈ 1`` with
        ``|λ| - 1`` up to ~1e-6 from the fit, and dropping it costs millimetres (found on the
        1D Table 6.1 runs); ``(1 + 1e-5)^5000 ≈ 1.05`` over a whole 2D run."""
        return self.select(np.flatnonzero(np.abs(np.asarray(self.eigs)) <= 1 + tol))

    def predict(self, x_start, n_steps: int, observe=None):
        """States ``x_{k₀+1} … x_{k₀+n}`` (n, N) from ``x_start``; with ``observe`` (o, N), only
        ``observe @ x`` (n, o) — e.g. the tracers — and the full fields are never formed."""
        return _predict(self, x_start, int(n_steps), observe)

    def scaled_mode_norms(self, x_start):
        """``‖φ_i b_i‖`` for every mode (the ranking of §7.4.1)."""
        return jnp.linalg.norm(self.modes, axis=0) * jnp.abs(self.amplitudes(x_start))


@functools.partial(jax.jit, static_argnums=2)
def _predict(model: DMDModel, x_start, n_steps: int, observe):
    """:meth:`DMDModel.predict` as one compiled program (op by op, each call of new shapes
    compiled every primitive on its own)."""
    b = model.amplitudes(x_start)
    P = model.modes if observe is None else observe.astype(model.modes.dtype) @ model.modes
    k = jnp.arange(1, n_steps + 1)
    powers = model.eigs[None, :] ** k[:, None]  # (n, r)
    return jnp.real((powers * b[None, :]) @ P.T)


@jax.jit
def _pairs_svd(X):
    return jnp.linalg.svd(X, full_matrices=False)


@functools.partial(jax.jit, static_argnums=4)
def _exact_dmd(U, s, Vh, Y, rank: int) -> DMDModel:
    U, s, V = U[:, :rank], s[:rank], Vh[:rank].conj().T
    YVS = Y @ V / s[None, :]
    A_tilde = U.conj().T @ YVS
    # eigenvector derivatives are valid for distinct eigenvalues, which DMD of real data has
    # generically; JAX asks for the opt-in explicitly
    eigs, W = jax.lax.linalg.eig(A_tilde, compute_left_eigenvectors=False, enable_eigvec_derivs=True)
    return DMDModel(eigs, YVS.astype(W.dtype) @ W)


SKETCH = 48  # columns of the randomized range finder (rank + oversampling)
SKETCH_MARGIN = 8  # the sketch must exceed the rank by this much, else the full SVD is taken


def fit_dmd(X, Y=None, rank: int | None = None, svd: str = "auto") -> DMDModel:
    """Exact DMD of snapshot pairs.

    **Arguments:** ``X`` (N, m) snapshots, and ``Y`` (N, m) their successors; with ``Y = None``
    the columns of ``X`` are one trajectory and the pairs are ``(X[:, :-1], X[:, 1:])``.
    ``rank``: SVD truncation (default: all non-negligible singular values, ``σ > σ₁ max(N, m) ε``).
    ``svd``: ``"full"`` (LAPACK's thin SVD), ``"randomized"`` (:func:`randomized_svd`, a
    sketch of :data:`SKETCH` columns, ``rank`` + :data:`SKETCH_MARGIN` with a given rank), or
    ``"auto"``: randomized where no rank is given and the sketch is at most half of ``m``, the
    full SVD taken instead when the rank found reaches the sketch less :data:`SKETCH_MARGIN`.
    Without a given rank the cut lies at round-off, so what the sketch leaves out is round-off
    too; a given rank over a noisy tail would make the sketch's error that of the gap, and takes
    the full SVD.
    **Returns:** :class:`DMDModel`.
    """
    if svd not in ("auto", "full", "randomized"):
        raise ValueError(f"svd = {svd!r}: one of auto, full, randomized")
    if Y is None:
        X, Y = _split_pairs(X)
    k = SKETCH if rank is None else int(rank) + SKETCH_MARGIN
    sketch = svd == "randomized" or (svd == "auto" and rank is None and 2 * k <= min(X.shape))
    U, s, Vh = randomized_svd(X, min(k, min(X.shape))) if sketch else _pairs_svd(X)
    if rank is not None:  # no look at the values: a given rank stays differentiable
        return _exact_dmd(U, s, Vh, Y, min(int(rank), s.shape[0]))
    r = numerical_rank(s, X.shape)
    if sketch and svd == "auto" and r > s.shape[0] - SKETCH_MARGIN:
        U, s, Vh = _pairs_svd(X)
        r = numerical_rank(s, X.shape)
    return _exact_dmd(U, s, Vh, Y, r)


def numerical_rank(s, shape) -> int:
    """How many singular values ``s`` of a matrix of ``shape`` lie above :func:`round_off_cut`
    (the rest are round-off)."""
    sv = np.asarray(s)
    return int(np.sum(sv > round_off_cut(sv, shape)))


def round_off_cut(s, shape):
    """``σ₁ max(N, m) ε``: the level below which the singular values ``s`` (descending) of a
    matrix of ``shape`` are round-off (NumPy or traced JAX arrays)."""
    return s[0] * max(shape) * np.finfo(s.dtype).eps


@functools.partial(jax.jit, static_argnums=(1, 2))
def randomized_svd(X, k: int, power_iterations: int = 1):
    """The leading ``k`` singular triplets ``(U (N, k), s (k,), Vh (k, m))`` of ``X`` by a
    randomized range finder (Halko, Martinsson & Tropp 2011, Alg. 4.4): ``Q = orth(X Ω)`` for a
    Gaussian ``Ω`` (m, k) of a fixed key, ``power_iterations`` subspace iterations re-orthonormalised
    at each half step (they sharpen the small singular values the rank cut reads), then the SVD
    of the small ``Qᵀ X``. Costs ``O(N m k)`` against the thin SVD's ``O(N m²)``."""
    omega = jax.random.normal(jax.random.PRNGKey(0), (X.shape[1], k), X.dtype)
    Q, _ = jnp.linalg.qr(X @ omega)
    for _ in range(power_iterations):
        Q, _ = jnp.linalg.qr(X.T @ Q)
        Q, _ = jnp.linalg.qr(X @ Q)
    Ub, s, Vh = jnp.linalg.svd(Q.T @ X, full_matrices=False)
    return Q @ Ub, s, Vh


class DMDForecast(eqx.Module):
    """:func:`dmd_forecast`'s result: ``observed`` (n_predict, o) the forecast observations of
    steps ``n_train + 1 … n_train + n_predict``; ``rank`` the numerical rank used; ``sketch_full``
    whether that rank reached the sketch less :data:`SKETCH_MARGIN` (where :func:`fit_dmd`
    would have taken the full SVD instead: the forecast may then miss directions, and the
    caller should fit with the full SVD)."""

    observed: jax.Array
    rank: jax.Array
    sketch_full: jax.Array


def dmd_forecast(model, options: RunOptions, n_predict: int, observe, tol: float = 1e-5) -> DMDForecast:
    """Snapshots, fit and forecast of single-configuration DMD as one compiled program.

    Runs ``options.n_steps`` full steps (``n_train``) of ``options.solver`` with ``options.dt``
    from ``model``'s initial state, fits exact DMD
    to the pre-transport first-order snapshots with the randomized range finder (a sketch of
    :data:`SKETCH` columns, :func:`randomized_svd`), keeps the modes with ``|λ| ≤ 1 + tol``
    (:meth:`DMDModel.stable`) and forecasts ``n_predict`` steps after the last snapshot,
    observed by ``observe`` (o, 2N). The numerical rank (:func:`numerical_rank`) is a mask here,
    not a shape: the directions below it get a zero inverse singular value, so their columns of
    ``Ã`` vanish, their eigenvalues are 0 and their modes zero; the other eigenpairs and modes are
    those of the rank-``r`` fit, and the least-squares amplitudes of the kept modes are unchanged.
    The forecast equals ``fit_dmd(Z).stable().predict(...)`` to round-off (where ``sketch_full``
    is false). ``n_train`` and ``n_predict`` are static (scan lengths); ``dt`` is traced.
    """
    return _dmd_forecast(model, options.solver, options.dt, int(options.n_steps), int(n_predict), observe, tol)


@eqx.filter_jit
def _dmd_forecast(model, solver, dt, n_train: int, n_predict: int, observe, tol: float) -> DMDForecast:
    _, Z, _ = collect_first_order(model, RunOptions(solver, n_train, dt))
    X, Y = Z[:, :-1], Z[:, 1:]
    k = min(SKETCH, *X.shape)
    U, s, Vh = randomized_svd(X, k)
    keep = s > round_off_cut(s, X.shape)
    s_inv = jnp.where(keep, 1.0 / jnp.where(keep, s, 1.0), 0.0)
    YVS = Y @ Vh.conj().T * s_inv[None, :]
    eigs, W = jax.lax.linalg.eig(U.conj().T @ YVS, compute_left_eigenvectors=False)
    modes = YVS.astype(W.dtype) @ W
    stable = (jnp.abs(eigs) <= 1 + tol) & (jnp.linalg.norm(modes, axis=0) > 0)
    modes = jnp.where(stable[None, :], modes, 0.0)
    b = jnp.linalg.lstsq(modes, Z[:, -1].astype(modes.dtype))[0]  # minimum norm: zero on the zero columns
    powers = eigs[None, :] ** jnp.arange(1, n_predict + 1)[:, None]
    observed = jnp.real((powers * b[None, :]) @ (observe.astype(modes.dtype) @ modes).T)
    rank = jnp.sum(keep)
    return DMDForecast(observed, rank, rank > k - SKETCH_MARGIN)


@jax.jit
def _split_pairs(X):
    return X[:, :-1], X[:, 1:]


def stack_trajectories(trajectories):
    """Snapshot pairs (eq. 6.12–6.13) from several trajectories, each (N, m_i): ``(X, Y)``."""
    X = jnp.concatenate([t[:, :-1] for t in trajectories], axis=1)
    Y = jnp.concatenate([t[:, 1:] for t in trajectories], axis=1)
    return X, Y


def dmd_coordinates(Z, fit, x_start, k: int) -> BasisTrajectory:
    """An exact-DMD prediction (:class:`~jaxbelt.rom.DMDModel`), as :func:`~jaxbelt.rom.error_estimate.error_rom` reads it,
    from ``x_start`` over ``k`` steps: ``x_start`` and ``Re(Φ Λʲ b)``, j = 1 … k, as coordinates in
    an orthonormal basis of the training snapshots ``Z`` (exact DMD modes lie in their span), so
    the full states are never formed. ``x_start`` is a full-order state: no initial error."""
    return coordinates_in(snapshot_basis(Z), fit, x_start, k)


def snapshot_basis(Z):
    """An orthonormal basis (2N, r) of the snapshots ``Z`` (their left singular vectors above
    round-off, :func:`numerical_rank`)."""
    U, s, _ = jnp.linalg.svd(jnp.asarray(Z), full_matrices=False)
    return U[:, : numerical_rank(s, Z.shape)]


def coordinates_in(Q, fit, x_start, k: int) -> BasisTrajectory:
    """:func:`dmd_coordinates` in a given orthonormal basis ``Q`` of the training snapshots."""
    b = fit.amplitudes(x_start)
    powers = fit.eigs[None, :] ** jnp.arange(1, k + 1)[:, None]
    coords = jnp.real((powers * b[None, :]) @ (Q.T.astype(fit.modes.dtype) @ fit.modes).T)
    return BasisTrajectory(basis=Q, coords=jnp.concatenate([(Q.T @ x_start)[None], coords]), z_true0=x_start)


class DMDReducedModel(AbstractReducedModel):
    """Exact DMD of one run fitted by :class:`DMD`: ``fit`` every mode, ``stable`` the modes with
    ``|λ| ≤ 1 + 1e-5`` (:meth:`DMDModel.stable`, the ones that predict), ``snapshots`` the
    pre-transport training snapshots (2N, m), ``basis`` an orthonormal basis of them
    (:func:`snapshot_basis`), ``observe`` (n_tr, 2N) the tracer operator on scaled first-order
    states."""

    fit: DMDModel
    stable: DMDModel
    snapshots: jax.Array
    basis: jax.Array
    observe: jax.Array

    @property
    def n_modes(self) -> int:
        return int(self.stable.eigs.shape[0])

    @property
    def modes_discarded(self) -> int:
        return int(self.fit.eigs.shape[0]) - self.n_modes

    def start(self, model, dt):
        """The run's own last training snapshot, after ``m`` steps: DMD continues its training run."""
        return int(self.snapshots.shape[1]), self.snapshots[:, -1]

    def predict(self, z0, mu, n_steps: int, observe=None) -> Prediction:
        """``mu`` is not read: the fit is of one configuration (``observe``, where given, is its
        own tracer operator)."""
        tracers = self.stable.predict(z0, n_steps, observe=self.observe if observe is None else observe)
        traj = coordinates_in(self.basis, self.stable, z0, int(n_steps))
        return Prediction(tracer_u=tracers, basis=traj.basis, coords=traj.coords, z_start=z0, order="pre")

    def spectra(self, z0) -> Spectra:
        return Spectra(singular_values=np.asarray(jnp.linalg.svd(self.snapshots[:, :-1], compute_uv=False)),
                       marked=int(self.fit.eigs.shape[0]), eigs=np.asarray(self.stable.eigs),
                       eig_weights=np.asarray(self.stable.scaled_mode_norms(z0)))


class DMD(AbstractReduction):
    """Exact DMD (module docstring) of the predicted configuration's own first steps, before
    transport, with ``modes`` modes (``None``: every non-negligible one); it continues that run
    from its last training snapshot. Its one training run is the predicted configuration."""

    modes: int | None = None
    name: ClassVar[str] = "dmd"

    def fit(self, training: TrainingRuns) -> DMDReducedModel:
        Zpre = collect_first_order(training.models[0], training.runs[0])[1]
        full = fit_dmd(Zpre, rank=self.modes)
        return DMDReducedModel(fit=full, stable=full.stable(), snapshots=Zpre, basis=snapshot_basis(Zpre),
                               observe=training.observe)

    def calibration_cases(self, fitted: DMDReducedModel, training: TrainingRuns, half: int):
        """The last third of the training window predicted by a fit on the first two thirds
        (``half`` is not read)."""
        Zpre, Cz = fitted.snapshots, fitted.observe
        m_train = int(Zpre.shape[1])
        C, N = tracer_operator(training.models[0]), training.models[0].n_unknowns
        k2 = max(2, (2 * m_train) // 3)
        if m_train - k2 < 1 or training.calibration_runs < 1:
            return
        cfit = fit_dmd(Zpre[:, :k2], rank=self.modes).stable()
        xs = Zpre[:, k2 - 1]
        yield training.models[0], (C @ Zpre[:N, k2:]).T, cfit.predict(xs, m_train - k2, observe=Cz), \
            dmd_coordinates(Zpre[:, :k2], cfit, xs, m_train - k2), training.solvers[0]

    def check(self, n_steps: int, train_steps: int):
        if train_steps < 2:
            raise ValueError(f"n_steps = {n_steps}, train_steps = {train_steps}: too few steps to train on "
                             "(at least 2)")
        if train_steps >= n_steps:
            raise ValueError(f"train_steps = {train_steps} with n_steps = {n_steps}: dmd predicts the steps after the "
                             "training window, so train_steps must be smaller than n_steps")

    def check_training(self, model, train, solvers):
        if any(m is not model for m in train):
            raise ValueError("dmd fits one configuration: the predicted model's own first train_steps steps")
        super().check_training(model, train, solvers)
