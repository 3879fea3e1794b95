"""DMD for configurations the model has not seen: DMD with control and parametric DMD.

The source fitted one DMD to snapshots of several configurations stacked together (eq. 6.12–6.13)
and found it could not predict a new configuration (§6.4.2, §7.4): a single linear map
``x_{k+1} = A x_k`` has no way to know *which* configuration it is in. Both models here give it
that information.

**DMD with control** (Proctor, Brunton & Kutz 2016, unknown ``B``): ``x_{k+1} ≈ A x_k + B u_k``
with the static misalignments as input, ``u = [μ; 1]`` (:func:`jaxbelt.rom.pod_step.parameters`
plus a constant for the parameter-free forcing), fitted in POD coordinates (see
:func:`fit_dmdc`); the prediction runs in the reduced coordinates ``ξ_{k+1} = Ã ξ_k + B̃ u_k``,
``x = V ξ``. The belt's step is affine in the misalignments (the fully reduced step's docstring
explains why), so this form is the right one, not a fit of convenience. The *drive rate* is
different: it sets the transport shift, which multiplies the state (a bilinear term), so a
DMDc model is valid at the drive speed(s) it was trained at — vary speeds with the parametric
DMD below. Input rows are scaled to the size of the state rows (and ``B̃`` rescaled), so that
millimetres, milliradians and rad/s do not decide the truncation.

**Parametric DMD** (the partitioned approach of Andreuzzi, Demo & Rozza 2023, as in PyDMD's
``ParametricDMD``): one POD basis for all training snapshots, one DMD per training configuration
in its coordinates, each DMD forecasting its own configuration, and the forecasts interpolated
in parameter space. The interpolation uses the minimum-norm weights ``w`` with
``Σ w_j μ_j = μ``, ``Σ w_j = 1`` — exact when the trajectory depends affinely on ``μ``, as the
belt's does to first order; the training set must contain the nominal configuration and one
run per varied parameter (or more).

*Start the trajectories after the start-up step.* The step out of the static initial state is
not on the low-rank dynamics that follow, and a per-configuration DMD fitted through it
forecasts its own configuration badly. On the 15-component 2D box of
``benchmarks/pdmd_2d.py`` (31 axial training runs, 400 steps, every 4th post-transport state;
held-out: ``three-roller-t72`` and 4 configurations with all 15 components misaligned, 1500
steps): with trajectories ``z_0, z_4, …`` the per-configuration forecasts err by 0.11 / 0.26 mm
(median / largest, longitudinal, common rank 40) and the held-out predictions by 0.10–0.14 mm
longitudinal, up to 1.1 mm lateral — the older 2D failure; with ``z_4, z_8, …`` the same fits
forecast their own configurations to 0.1–0.2 µm and the held-out tracer RMSE is 0.13–0.50 µm
longitudinal and 0.01–0.41 µm lateral (0.02–0.48 / 0.001–0.04 µm with ``dmd_rank=40``, which
equals the error of interpolating the *full* training trajectories with the same weights, the
affine floor of the box, and DMDc's). The weights are not what amplifies: with the axial
design ``Σ |w_j|`` is 2.9–7.9 there. The stability cut changes nothing on that box. The
prediction's ``k = 0`` is then the trajectories' first snapshot (step 4 there); the test
configuration's own state is never needed.

Both are frozen Modules (``jit``/``grad`` go through fit and prediction) with ``predict``
returning tracers only when given an observation matrix.
"""

from __future__ import annotations

import functools
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .dmd import DMDModel, fit_dmd, numerical_rank
from .error_estimate import BasisTrajectory
from .pod import choose_modes
from .pod_step import parameters
from .reduced_model import AbstractReducedModel, AbstractReduction, Prediction, Spectra, TrainingRuns, observation
from .snapshots import collect_first_order, tracer_operator


def _rank(s, shape, rank):
    if rank is not None:
        return int(min(rank, s.shape[0]))
    return numerical_rank(s, shape)


class DMDcModel(eqx.Module):
    """Fitted DMD with control: ``basis`` Û (N, r), ``A`` (r, r), ``B`` (r, l)."""

    basis: jax.Array
    A: jax.Array
    B: jax.Array

    @property
    def eigs(self):
        return jnp.linalg.eigvals(self.A)

    @property
    def modes(self):
        """DMD modes ``Û W`` of the reduced operator (projected modes)."""
        return self.basis.astype(complex) @ jnp.linalg.eig(self.A)[1]

    def amplitudes(self, x_start, W=None):
        """Mode amplitudes ``b = W⁻¹ Ûᵀ x_start`` of a start state (the free response's); ``W``
        the eigenvectors of ``Ã`` if already at hand."""
        W = jnp.linalg.eig(self.A)[1] if W is None else W
        return jnp.linalg.solve(W, (self.basis.T @ x_start).astype(W.dtype))

    def scaled_mode_norms(self, x_start):
        """``‖φ_i b_i‖`` for every mode of the free response from ``x_start`` (as
        :meth:`jaxbelt.rom.DMDModel.scaled_mode_norms`; ``Û`` orthonormal, so ``‖φ_i‖ = ‖w_i‖``)."""
        W = jnp.linalg.eig(self.A)[1]
        return jnp.linalg.norm(W, axis=0) * jnp.abs(self.amplitudes(x_start, W))

    @property
    def B_full(self):
        """The input matrix in full coordinates, ``Û B̃`` (N, l)."""
        return self.basis @ self.B

    def predict(self, x_start, inputs, n_steps: int, observe=None):
        """States ``x_1 … x_n`` (n, N) from ``x_start`` under ``inputs`` (l,) constant or (n, l)
        per step (the input acting on the step that produces ``x_k``); with ``observe`` (o, N) only
        ``observe @ x`` (n, o)."""
        inputs = jnp.broadcast_to(jnp.asarray(inputs, self.B.dtype), (n_steps, self.B.shape[1]))
        out = self.basis if observe is None else observe @ self.basis

        def body(xi, u):
            xi = self.A @ xi + self.B @ u
            return xi, out @ xi

        return jax.lax.scan(body, self.basis.T @ x_start, inputs)[1]


def _input_scale(U, ref):
    """Per-row factors bringing the input rows to the rms size of ``ref`` (zero rows left alone)."""
    row = jnp.sqrt(jnp.mean(U**2, axis=1))
    return jnp.where(row > 0, jnp.sqrt(jnp.mean(ref**2)) / jnp.where(row > 0, row, 1.0), 1.0)


def fit_dmdc(X, Y, U, rank: int | None = None, rank_out: int | None = None, method: str = "pod",
             rtol: float = 1e-8, scale_inputs: bool = True) -> DMDcModel:
    """DMD with control, ``B`` unknown.

    **Arguments:** snapshot pairs ``X``, ``Y`` (N, m) and the inputs ``U`` (l, m) acting between
    them.

    * ``method="pod"`` (default): POD basis ``V`` (rank ``rank``) of ``[X Y]``, reduced data
      ``Ξ = VᵀX``, ``Ξ' = VᵀY``, and ``[Ã B̃] = Ξ' [Ξ; Υ]⁺`` by a pseudo-inverse truncated at
      ``rtol`` relative to the largest singular value. On the belt the prescribed roller DOFs
      in the state *equal* inputs, so ``[Ξ; Υ]`` is nearly rank-deficient; truncating it
      (not the state) is what keeps ``B̃`` from amplifying round-off. Measured on the 1D
      held-out test (``benchmarks/rom_1d.py``): 0.0014 mm where Proctor's form gives 0.018 mm
      at its best rank and grows with it.
    * ``method="proctor"``: the algorithm of Proctor, Brunton & Kutz (2016) (and PyDMD's
      ``DMDc``): ``Ω = [X; Υ]`` truncated at ``rank`` (``p``), ``Y`` at ``rank_out`` (``r``),
      ``Ã = Ûᵀ Y Ṽ Σ̃⁻¹ Ũ₁ᵀ Û``, ``B̃ = Ûᵀ Y Ṽ Σ̃⁻¹ Ũ₂ᵀ``.

    Ranks default to every non-negligible singular value.
    """
    X, Y, U = jnp.asarray(X), jnp.asarray(Y), jnp.asarray(U, X.dtype)
    N = X.shape[0]
    if method == "pod":
        Vb, sb, _ = jnp.linalg.svd(jnp.concatenate([X, Y], axis=1), full_matrices=False)
        r = _rank(sb, (N, 2 * X.shape[1]), rank)
        return fit_dmdc_in_basis(Vb[:, :r], X, Y, U, rtol=rtol, scale_inputs=scale_inputs)
    if method != "proctor":
        raise ValueError(f"unknown DMDc method {method!r} (use 'pod' or 'proctor')")
    scale = _input_scale(U, X) if scale_inputs else jnp.ones(U.shape[0], X.dtype)
    Omega = jnp.concatenate([X, U * scale[:, None]], axis=0)
    Ut, st, Vth = jnp.linalg.svd(Omega, full_matrices=False)
    p = _rank(st, Omega.shape, rank)
    Ut, st, Vt = Ut[:, :p], st[:p], Vth[:p].T
    Uh, sh, _ = jnp.linalg.svd(Y, full_matrices=False)
    Uh = Uh[:, : _rank(sh, Y.shape, rank_out)]
    YVS = Y @ Vt / st[None, :]
    A = Uh.T @ YVS @ (Ut[:N].T @ Uh)
    B = Uh.T @ YVS @ Ut[N:].T * scale[None, :]
    return DMDcModel(Uh, A, B)


def fit_dmdc_in_basis(V, X, Y, U, rtol: float = 1e-8, scale_inputs: bool = True) -> DMDcModel:
    """DMD with control in a given orthonormal basis ``V`` (N, r) (:func:`fit_dmdc`'s ``"pod"``
    method after its SVD): ``[Ã B̃] = VᵀY [VᵀX; Υ]⁺``, the pseudo-inverse truncated at ``rtol``
    and the input rows scaled as there."""
    X, Y = jnp.asarray(X), jnp.asarray(Y)
    U = jnp.asarray(U, X.dtype)
    r = V.shape[1]
    Xi, Yi = V.T @ X, V.T @ Y
    scale = _input_scale(U, Xi) if scale_inputs else jnp.ones(U.shape[0], X.dtype)
    AB = Yi @ jnp.linalg.pinv(jnp.concatenate([Xi, U * scale[:, None]], axis=0), rtol=rtol)
    return DMDcModel(V, AB[:, :r], AB[:, r:] * scale[None, :])


def belt_inputs(mu, n_steps: int):
    """DMDc inputs ``[μ; 1]`` repeated over ``n_steps`` (l, n_steps) for one configuration."""
    mu = jnp.asarray(mu)
    return jnp.broadcast_to(jnp.concatenate([mu, jnp.ones(1, mu.dtype)])[:, None], (mu.size + 1, n_steps))


def interpolation_weights(P, mu):
    """Minimum-norm weights ``w`` (J,) with ``Σ w_j P_j = μ`` and ``Σ w_j = 1`` (affine
    reproduction) for training parameters ``P`` (J, d); least squares if ``μ`` is outside
    their affine hull."""
    P = jnp.asarray(P)
    Aff = jnp.concatenate([P.T, jnp.ones((1, P.shape[0]), P.dtype)], axis=0)
    # scale each parameter row so unit choices do not weigh the least squares
    rs = jnp.max(jnp.abs(Aff), axis=1, keepdims=True)
    rs = jnp.where(rs > 0, rs, 1.0)
    rhs = jnp.concatenate([jnp.asarray(mu, P.dtype), jnp.ones(1, P.dtype)])[:, None] / rs
    return (jnp.linalg.pinv(Aff / rs) @ rhs)[:, 0]


class ParametricDMDModel(eqx.Module):
    """Partitioned parametric DMD: ``basis`` (N, r), per training configuration a reduced DMD
    (``eigs`` (J, k), ``modes`` (J, r, k) padded with zeros), amplitudes ``b`` (J, k) from each
    configuration's first snapshot, and the training parameters ``params`` (J, d)."""

    basis: jax.Array
    eigs: jax.Array
    modes: jax.Array
    amplitudes: jax.Array
    params: jax.Array

    def coefficients(self, n_steps: int):
        """Reduced forecasts ``ξ^j_k`` for k = 0 … n-1 of every training configuration (J, n, r)."""
        k = jnp.arange(n_steps)
        powers = self.eigs[:, None, :] ** k[None, :, None]  # (J, n, k)
        return jnp.real(jnp.einsum("jnk,jrk->jnr", powers * self.amplitudes[:, None, :], self.modes))

    def predict(self, mu, n_steps: int, observe=None):
        """States ``x_0 … x_{n-1}`` (n, N) — or ``observe @ x`` (n, o) — of configuration ``mu``."""
        w = interpolation_weights(self.params, mu)
        xi = jnp.einsum("j,jnr->nr", w, self.coefficients(n_steps))
        out = self.basis if observe is None else observe @ self.basis
        return xi @ out.T


def fit_parametric_dmd(trajectories, params, rank: int | None = None, dmd_rank: int | None = None,
                       energy_tol: float | None = None, discard_unstable: bool = True,
                       unstable_tol: float = 1e-5, basis=None) -> ParametricDMDModel:
    """Parametric DMD from training ``trajectories`` (list of (N, m_j) snapshot sequences, all on
    one time axis: each starting at the same step of its configuration — in 2D one or a few
    steps after the initial state, see the module docstring) with parameters ``params`` (J, d).

    ``rank``: common POD basis size (or ``energy_tol``, eq. 5.11); ``basis``: the common basis
    given (N, R) orthonormal columns, e.g. the left singular vectors of all trajectories from one
    SVD reused over a rank study — its first ``rank`` columns (all by default) are used and no
    SVD is computed; ``dmd_rank``: SVD truncation of
    each per-configuration DMD (default: all non-negligible). ``discard_unstable``: drop modes
    with ``|λ| > 1 + unstable_tol`` (the source's rule, §6.4.1) — over thousands of steps a
    spurious growing mode of one configuration, multiplied by its interpolation weight, ruins the
    prediction. The tolerance is not round-off: the mode that carries the static offset sits at
    ``λ ≈ 1`` with ``|λ| - 1`` up to ~1e-6 from the fit, and dropping it costs far more than it
    saves (1D held-out test: 0.65 mm with 1e-8, 0.013 mm with 1e-5; ``(1 + 1e-5)^5000 = 1.05``). Check the error indicator (:mod:`jaxbelt.rom.error_estimate`) on long horizons.
    """
    if basis is not None:
        V = jnp.asarray(basis)[:, :rank]
    else:
        Xall = jnp.concatenate([jnp.asarray(t) for t in trajectories], axis=1)
        U, s, _ = jnp.linalg.svd(Xall, full_matrices=False)
        if energy_tol is not None:
            r = choose_modes(np.asarray(s), energy_tol=energy_tol)
        else:
            r = _rank(s, Xall.shape, rank)
        V = U[:, :r]
    reduced = [V.T @ jnp.asarray(t) for t in trajectories]  # each configuration's coefficients
    fits = [fit_dmd(xi, rank=dmd_rank) for xi in reduced]
    k = max(f.eigs.shape[0] for f in fits)
    eigs = jnp.stack([jnp.pad(f.eigs, (0, k - f.eigs.shape[0])) for f in fits])
    modes = jnp.stack([jnp.pad(f.modes, ((0, 0), (0, k - f.modes.shape[1]))) for f in fits])
    amps = jnp.stack([jnp.pad(f.amplitudes(xi[:, 0]), (0, k - f.eigs.shape[0])) for f, xi in zip(fits, reduced)])
    if discard_unstable:
        amps = jnp.where(jnp.abs(eigs) > 1 + unstable_tol, 0.0, amps)
    return ParametricDMDModel(V, eigs, modes, amps, jnp.asarray(params))


def stack_controlled(trajectories, inputs):
    """Snapshot pairs and inputs ``(X, Y, U)`` from several trajectories (N, m_j) with their
    input sequences (l, m_j - 1) — eq. 6.12–6.13 with the input rows alongside."""
    X = jnp.concatenate([t[:, :-1] for t in trajectories], axis=1)
    Y = jnp.concatenate([t[:, 1:] for t in trajectories], axis=1)
    return X, Y, jnp.concatenate(list(inputs), axis=1)


@functools.partial(jax.jit, static_argnums=3)
def prediction_trajectory(fit: DMDcModel, z0, u, n_steps: int) -> BasisTrajectory:
    """A DMDc prediction of ``n_steps`` steps from ``z0`` under the input ``u`` as
    :func:`~jaxbelt.rom.error_estimate.error_rom` reads it (the start projected, the full ``z0`` as
    the true start)."""
    coords = jnp.concatenate([(fit.basis.T @ z0)[None], fit.predict(z0, u, n_steps, observe=fit.basis.T)])
    return BasisTrajectory(fit.basis, coords, z0)


def calibration_cases(cfit: DMDcModel, runs, steps: int):
    """:func:`~jaxbelt.rom.calibration.calibrate`'s cases for a DMDc fit ``cfit`` predicting
    training runs it has partly seen: for each ``(model, Z, μ, solver)`` of ``runs`` (``Z``
    the run's post-transport snapshots, (2N, steps + 1)), the run's tracers (at ``model``'s
    tracer positions), the fit's prediction of them from ``Z[:, 0]`` over ``steps`` steps, that
    prediction as a :class:`~jaxbelt.rom.error_estimate.BasisTrajectory`, and the solver."""
    for m, Z, mu, solver in runs:
        C = tracer_operator(m)
        N, Cz = C.shape[1], observation(m)
        u = belt_inputs(mu, 1)[:, 0]
        yield (m, (C @ Z[:N, 1:]).T, cfit.predict(Z[:, 0], u, steps, observe=Cz),
               prediction_trajectory(cfit, Z[:, 0], u, steps), solver)



def _post_transport_runs(training: TrainingRuns) -> tuple:
    """The post-transport snapshots ``Z_post`` (2N, n_steps + 1) of every training run."""
    return tuple(collect_first_order(m, training.runs[i])[2] for i, m in enumerate(training.models))


def _controlled_pairs(trajectories, params):
    """:func:`stack_controlled` of the runs ``trajectories`` under their constant inputs ``[μ; 1]``."""
    return stack_controlled(trajectories, [belt_inputs(p, Z.shape[1] - 1) for p, Z in zip(params, trajectories)])


@functools.partial(jax.jit, static_argnums=3)
def _dmdc_tracers(fit: DMDcModel, z0, u, n_steps: int, observe):
    return fit.predict(z0, u, n_steps, observe=observe)


class DMDcReducedModel(AbstractReducedModel):
    """DMD with control fitted by :class:`DMDc`: ``fit`` (:class:`DMDcModel`), the training runs'
    post-transport ``trajectories`` and parameters ``params``, ``observe`` (n_tr, 2N) the nominal
    training configuration's tracer operator on scaled first-order states (a prediction takes the
    predicted configuration's)."""

    fit: DMDcModel
    trajectories: tuple
    params: tuple
    observe: jax.Array

    @property
    def n_modes(self) -> int:
        return int(self.fit.A.shape[0])

    def predict(self, z0, mu, n_steps: int, observe=None) -> Prediction:
        u = belt_inputs(mu, 1)[:, 0]
        tracers = _dmdc_tracers(self.fit, z0, u, int(n_steps), self.observe if observe is None else observe)
        traj = prediction_trajectory(self.fit, z0, u, int(n_steps))
        return Prediction(tracer_u=tracers, basis=traj.basis, coords=traj.coords, z_start=z0, order="post")

    def spectra(self, z0) -> Spectra:
        X, Y, _ = _controlled_pairs(self.trajectories, self.params)
        return Spectra(singular_values=np.asarray(jnp.linalg.svd(jnp.concatenate([X, Y], axis=1), compute_uv=False)),
                       eigs=np.asarray(self.fit.eigs), eig_weights=np.asarray(self.fit.scaled_mode_norms(z0)))


class DMDc(AbstractReduction):
    """DMD with control (module docstring) of ``modes`` modes, trained on the post-transport
    snapshots of every training run with their parameters as inputs; it predicts any
    configuration from its initial state (at the drive speeds it was trained at)."""

    modes: int = 30
    name: ClassVar[str] = "dmdc"

    def fit(self, training: TrainingRuns) -> DMDcReducedModel:
        trajs = _post_transport_runs(training)
        return self.fitted(trajs, training)

    def fitted(self, trajectories, training: TrainingRuns, fit: DMDcModel | None = None) -> DMDcReducedModel:
        """The reduced model of the training runs' post-transport ``trajectories``: ``fit`` where
        given (a sized training's, :func:`~jaxbelt.rom.sizing.train_over_box`), else fitted here."""
        params = tuple(parameters(m) for m in training.models)
        if fit is None:
            fit = fit_dmdc(*_controlled_pairs(trajectories, params), rank=self.modes)
        return DMDcReducedModel(fit=fit, trajectories=tuple(trajectories), params=params, observe=training.observe)

    def calibration_cases(self, fitted: DMDcReducedModel, training: TrainingRuns, half: int):
        cfit = fit_dmdc(*_controlled_pairs([Z[:, :half + 1] for Z in fitted.trajectories], fitted.params),
                        rank=self.modes)
        runs = training.calibration_subset(zip(training.models, fitted.trajectories, fitted.params, training.solvers))
        return calibration_cases(cfit, runs, int(training.n_steps))

    def check_training(self, model, train, solvers):
        if len(train) < 2:
            raise ValueError("dmdc needs at least two training models (the nominal configuration plus one run per "
                             "varied parameter)")
        super().check_training(model, train, solvers)


class ParametricDMDReducedModel(AbstractReducedModel):
    """Parametric DMD fitted by :class:`ParametricDMD`: ``fit`` (:class:`ParametricDMDModel`)
    of the training runs' post-transport ``trajectories`` from step ``skip`` on, their
    parameters ``params``, ``observe`` (n_tr, 2N) the nominal training configuration's tracer
    operator on scaled first-order states (a prediction takes the predicted configuration's)."""

    fit: ParametricDMDModel
    trajectories: tuple
    params: tuple
    observe: jax.Array
    skip: int = eqx.field(static=True)

    @property
    def n_modes(self) -> int:
        return int(self.fit.basis.shape[1])

    @property
    def training_starts_at_step(self) -> int:
        return self.skip

    def predict(self, z0, mu, n_steps: int, observe=None) -> Prediction:
        """The states of configuration ``mu`` (interpolated between the training runs' forecasts,
        which start from their own states: ``z0`` is the start of the coordinates only), observed
        by ``observe``."""
        n = int(n_steps)
        tracers = _pdmd_forecast(self.fit, mu, n, self.observe if observe is None else observe, self.skip)
        coords = _pdmd_coordinates(self.fit, mu, n, z0, self.skip)
        return Prediction(tracer_u=tracers, basis=self.fit.basis, coords=coords, z_start=z0, order="post")

    def spectra(self, z0) -> Spectra:
        w = (np.abs(np.asarray(self.fit.amplitudes)) * np.linalg.norm(np.asarray(self.fit.modes), axis=1)).reshape(-1)
        keep = w > 0  # not the padding of the per-configuration DMDs
        return Spectra(singular_values=np.asarray(jnp.linalg.svd(jnp.concatenate(self.trajectories, axis=1),
                                                                 compute_uv=False)),
                       eigs=np.asarray(self.fit.eigs).reshape(-1)[keep], eig_weights=w[keep])


def _pdmd_forecast_eager(fit, p, steps: int, observe, skip: int):
    """States 1 … steps of the configuration ``p`` observed by ``observe``."""
    return fit.predict(p, steps + 1 - skip, observe=observe)[1 - skip:]


_pdmd_forecast = jax.jit(_pdmd_forecast_eager, static_argnums=(2, 4))


def _pdmd_coordinates(fit, p, steps: int, z_start, skip: int):
    """Reduced coordinates of steps 0 … steps (step 0: the start state projected)."""
    if not skip:  # the forecast starts at step 0 itself
        return fit.predict(p, steps + 1, observe=fit.basis.T)
    return jnp.concatenate([(fit.basis.T @ z_start)[None], _pdmd_forecast_eager(fit, p, steps, fit.basis.T, skip)])


class ParametricDMD(AbstractReduction):
    """Parametric DMD (module docstring) with a common basis of ``modes`` modes, trained on the
    post-transport snapshots of every training run — in 2D from step 1 on (the start-up step
    from the static state is no linear recurrence of the later states: with it the 2D forecasts
    are off by ~0.1 mm, from step 1 on by < 1 µm, ``benchmarks/pdmd_2d.py``); it predicts any
    configuration (drive speeds included) from the training runs' forecasts."""

    modes: int = 30
    name: ClassVar[str] = "pdmd"

    def fit(self, training: TrainingRuns) -> ParametricDMDReducedModel:
        skip = 1 if training.models[0].kind == "2d" else 0
        trajs = _post_transport_runs(training)
        params = tuple(parameters(m) for m in training.models)
        fit = fit_parametric_dmd([Z[:, skip:] for Z in trajs], jnp.stack(params), rank=self.modes)
        return ParametricDMDReducedModel(fit=fit, trajectories=trajs, params=params, observe=training.observe,
                                         skip=skip)

    def calibration_cases(self, fitted: ParametricDMDReducedModel, training: TrainingRuns, half: int):
        skip, m_train = fitted.skip, int(training.n_steps)
        cfit = fit_parametric_dmd([Z[:, skip:half + 1] for Z in fitted.trajectories], jnp.stack(fitted.params),
                                  rank=self.modes)
        for m, s, p, Z in training.calibration_subset(zip(training.models, training.solvers, fitted.params,
                                                          fitted.trajectories)):
            C, N, Cz = tracer_operator(m), m.n_unknowns, observation(m)  # each run at its own tracers
            yield m, (C @ Z[:N, 1:]).T, _pdmd_forecast_eager(cfit, p, m_train, Cz, skip), BasisTrajectory(
                cfit.basis, _pdmd_coordinates(cfit, p, m_train, Z[:, 0], skip), Z[:, 0]), s

    def check_training(self, model, train, solvers):
        if len(train) < 2:
            raise ValueError("pdmd needs at least two training models (the nominal configuration plus one run per "
                             "varied parameter)")
        super().check_training(model, train, solvers)


__all__ = ["DMDcModel", "fit_dmdc", "fit_dmdc_in_basis", "ParametricDMDModel", "fit_parametric_dmd", "interpolation_weights",
           "belt_inputs", "stack_controlled", "DMDModel", "prediction_trajectory", "calibration_cases", "DMDc",
           "DMDcReducedModel", "ParametricDMD", "ParametricDMDReducedModel"]
