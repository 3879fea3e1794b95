"""Train a reduced model, predict one configuration with it and compare with the full model: the
whole of ``jaxbelt reduce`` as one function, :func:`reduce_and_compare`.

**Methods** (:class:`~jaxbelt.rom.reduced_model.AbstractReduction`, chosen by the object in
:attr:`ReduceConfig.method`): :class:`~jaxbelt.rom.ReducedPOD` the fully reduced POD step
(:func:`~jaxbelt.rom.pod_step.fit_reduced_pod`), linearised at the first training configuration
and run with the predicted one's parameters, predicting every step from its initial state;
:class:`~jaxbelt.rom.DMD` exact DMD of the predicted configuration's own pre-transport
snapshots, predicting the steps after the training window from its last snapshot (modes with
``|λ| > 1 + 1e-5`` dropped, :meth:`~jaxbelt.rom.DMDModel.stable`); :class:`~jaxbelt.rom.DMDc`
DMD with control and :class:`~jaxbelt.rom.ParametricDMD` parametric DMD
(:mod:`jaxbelt.rom.dmdc`), trained on several configurations, predicting a new one from its
initial state. The error is the tracer RMSE over the predicted steps, at the full run's recorded
steps, in µm; every method observes its prediction at the predicted configuration's tracers
(:func:`~jaxbelt.rom.reduced_model.observation`).

**Error estimate** (``stride > 0``): the error ROM
(:func:`~jaxbelt.rom.error_estimate.error_rom`) of the prediction times a safety factor
calibrated on the training data only (:func:`~jaxbelt.rom.calibration.calibrate`): the same fit
on the first half of the training window (DMD: the first two thirds) predicting the first
training runs (at most :data:`~jaxbelt.rom.reduced_model.CALIBRATION_RUNS`) over the whole
window.

**Cost**: where a ``clock`` is given (:func:`jaxbelt.bench.timing.warm_best`), the training runs
with the fit (offline), the prediction (online), the error estimate of the prediction and the
calibration of its safety factor (each timed once) are timed by it; the full runs and the
choice of the solver mode the training runs use are measured in :mod:`jaxbelt.bench.reduction`
(``jaxbelt reduce``), which passes that choice here (``reuse_factors``).
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from ..integrators import DirectBackwardEuler, Reuse
from ..timeloop import SaveAt, simulate
from .calibration import calibrate
from .comparison import FullRunDivergedError, ReducedRunDivergedError, ReductionCost, ReductionEstimate, ReductionResult
from .config import ReduceConfig
from .dmdc import DMDc
from .error_estimate import error_rom
from .metrics import rmse, rrmse
from .pod_step import parameters
from .reduced_model import AbstractReducedModel, Prediction, TrainingRuns, observation



def reuse_mode(solver):
    """``solver``'s reuse mode: direct Backward Euler with the factors frozen at the run's start
    (:class:`jaxbelt.Reuse`), the same transport rule (``solver`` itself where it is that already)."""
    if is_reuse(solver):
        return solver
    return DirectBackwardEuler(Reuse(), transport=solver.transport)


def is_reuse(solver) -> bool:
    """Whether ``solver`` is a reuse mode (:func:`reuse_mode`)."""
    return isinstance(solver, DirectBackwardEuler) and isinstance(solver.linear_solver, Reuse)


def full_run(model, solver, config: ReduceConfig):
    """The predicted configuration's full-order run (:class:`~jaxbelt.Trajectory`) with ``solver``
    over ``config.options``' steps, recorded every ``options.saveat.every``, that
    :func:`reduce_and_compare` compares with."""
    o = config.options
    return simulate(model, solver, n_steps=o.n_steps, dt=o.dt, saveat=SaveAt(every=o.saveat.every), check=False)[1]


def _once(f, **_):
    """A clock that does not time: ``(f(), None, None)``."""
    return f(), None, None


def reduce_and_compare(model, train, config: ReduceConfig, train_solvers=None, trained=None, *, full_trajectory=None,
                       reuse_factors: bool = False, clock: Callable | None = None) -> ReductionResult:
    """Train ``config.method`` on the ``train`` models (dmd: ``model`` itself), predict ``model``
    over ``config.options.n_steps`` steps and compare with its full-order run (module docstring).

    **Arguments:** ``model`` the configuration predicted; ``train`` the training configurations
    (same mesh; pod is linearised at the first; dmdc/pdmd need at least two: the nominal
    configuration plus one run per varied parameter); ``config`` (:class:`ReduceConfig`);
    ``train_solvers`` each training model's own solver (default ``config.options.solver``);
    ``trained`` (dmdc only) a :class:`~jaxbelt.rom.sizing.BoxTraining` sized to a tolerance: its
    training runs and fit are used as they are (``train`` is then its models, the training steps
    and modes its own), and its loop's time, compilation included, is the offline time;
    ``full_trajectory`` the predicted configuration's full run (:func:`full_run`; run here when
    ``None``); ``reuse_factors`` whether the training runs (and the error estimate's full steps)
    use each solver's reuse mode (:func:`reuse_mode`) instead of the solver itself; ``clock``
    ``clock(f, repeat=…, budget_s=…) -> (f(), seconds, first-call seconds)`` timing the
    training with the fit, the prediction and, called once (``repeat=0``: the first call's
    seconds), the error estimate and its calibration (``None``: not timed, ``cost`` is ``None``).

    **Raises:** ``ValueError`` on an unusable training set, :class:`FullRunDivergedError`,
    :class:`ReducedRunDivergedError`.
    """
    solver = config.options.solver
    method = config.method
    if trained is not None:
        if not isinstance(method, DMDc):
            raise ValueError(f"a sized training (trained=) is a DMDc model; method is {method.name!r}")
        train = trained.models
        config = dataclasses.replace(config, train_steps=trained.train_steps, method=DMDc(modes=trained.modes))
        method = config.method
    train = tuple(train) if train else (model,)
    train_solvers = tuple(train_solvers) if train_solvers is not None else (solver,) * len(train)
    if len(train_solvers) != len(train):
        raise ValueError(f"{len(train_solvers)} training solvers for {len(train)} training models")
    method.check_training(model, train, train_solvers)
    n, dt = config.options.n_steps, config.options.dt

    traj = full_run(model, solver, config) if full_trajectory is None else full_trajectory
    if not np.all(np.isfinite(np.asarray(traj.tracer_u))):
        raise FullRunDivergedError("the full simulation diverged; nothing to compare with")
    mode = reuse_mode if reuse_factors else (lambda s: s)
    test_solver = mode(solver)
    runs = tuple(config.options.replace(solver=mode(s), n_steps=config.train_window) for s in train_solvers)
    training = TrainingRuns(models=train, runs=runs, own_solvers=train_solvers, calibration_runs=config.calibration_runs)
    clock = _once if clock is None else clock

    if trained is not None:  # the sized training's runs and fit (its calibration is taken too)
        fitted = method.fitted(trained.trajectories, training, fit=trained.fit)
        offline_s = first_s = trained.seconds
    else:
        fitted, offline_s, first_s = clock(lambda: method.fit(training), repeat=1)
    start, z0 = fitted.start(model, dt)
    mu, observe = parameters(model), observation(model)  # the predicted configuration's tracers
    prediction, online_s, _ = clock(lambda: fitted.predict(z0, mu, n - start, observe), repeat=5, budget_s=0.5)

    pred = np.asarray(prediction.tracer_u)
    if not np.all(np.isfinite(pred)):
        bad = int(np.argmax(~np.all(np.isfinite(pred.reshape(len(pred), -1)), axis=1)))
        raise ReducedRunDivergedError(
            f"the {method.name} reduced model ({fitted.n_modes} modes) diverged: its prediction is not finite from "
            f"step {start + bad + 1}; the projected step is unstable at this rank — use fewer modes (the fully "
            "reduced POD step of three-roller at 80 modes: benchmarks/rom_box_2d.py)")
    # compare at the full run's output steps inside the predicted window (start, n]
    steps_full = np.rint(np.asarray(traj.t) / dt).astype(int)
    rows = np.flatnonzero((steps_full > start) & (steps_full <= n))
    at = steps_full[rows] - start - 1
    truth, pred = np.asarray(prediction.full_tracer_u(traj))[rows], pred[at]
    err_t = np.sqrt(np.mean((truth - pred) ** 2, axis=1)) * 1e6
    estimate, estimate_s, calibration_s = None, None, None
    if config.stride > 0:
        estimate, estimate_s, calibration_s = _estimate(model, method, fitted, training, prediction, config,
                                                        test_solver, at, n - start, trained, clock)
    cost = None if online_s is None else ReductionCost(offline_s=offline_s, offline_first_call_s=first_s,
                                                      online_s=max(online_s, 1e-12), estimate_s=estimate_s,
                                                      calibration_s=calibration_s)
    return ReductionResult(
        method=method, modes=fitted.n_modes, modes_discarded=fitted.modes_discarded,
        training_starts_at_step=fitted.training_starts_at_step, train_steps=config.train_window,
        n_train_runs=len(train), n_steps=n, predict_from_step=start, compared=prediction.compared,
        n_unknowns=model.n_unknowns, n_tracers=model.n_tracers, rmse_um=float(rmse(truth, pred)) * 1e6,
        rrmse=float(rrmse(truth, pred)), max_rmse_over_time_um=float(np.max(err_t)) if err_t.size else None,
        t=steps_full[rows] * float(dt), error_um=err_t, estimate=estimate, cost=cost,
        spectra=fitted.spectra(z0) if config.spectra else None, sizing=None if trained is None else trained.levels)


def _estimate(model, method, fitted: AbstractReducedModel, training: TrainingRuns, prediction: Prediction,
              config: ReduceConfig, solver, at, predicted_steps: int, trained, clock: Callable):
    """``(estimate, seconds, calibration seconds)``: the error ROM of the prediction, calibrated on
    the training data (module docstring), each timed once by ``clock`` (the calibration of a sized
    training is its own: 0 s here); ``at`` the prediction's rows at the compared steps."""
    traj = prediction.trajectory
    est, estimate_s, _ = clock(lambda: error_rom(model, traj.basis, traj.coords, config.options.dt, traj.z_true0,
                                                 stride=config.stride, order=prediction.order, solver=solver,
                                                 options=config.estimate), repeat=0)
    if trained is not None:  # calibrated on the same fit and training runs already
        cal, calibration_s = trained.calibration, None if estimate_s is None else 0.0
    else:
        cal, calibration_s, _ = clock(lambda: calibrate(
            method.calibration_cases(fitted, training, max(1, config.train_window // 2)), config.options.dt,
            stride=config.stride, order=prediction.order, options=config.estimate), repeat=0)
    kappa = cal.safety_factor
    est_t = kappa * np.asarray(est.error_um)[at]
    some = bool(est_t.size)
    return ReductionEstimate(
        error_um=est_t, rmse_um=float(np.sqrt(np.mean(est_t**2))) if some else None,
        max_um=float(np.max(est_t)) if some else None,
        raw_rmse_um=float(np.sqrt(np.mean((est_t / kappa) ** 2))) if some else None, safety_factor=kappa,
        calibration=cal.cases, subspace_dim=est.dim, projected_spectral_radius=est.rho, cost=est.cost,
        full_steps_predicted=predicted_steps), estimate_s, calibration_s
