"""Trusting the error estimate, and choosing how much to train on, from training data alone.

:func:`calibrate` turns :func:`~jaxbelt.rom.error_estimate.error_rom`'s raw estimate into a bound: it
predicts part of the training data with a model fitted on the rest, where the true error is
known, and scales the estimate by ``SAFETY_MARGIN / min(1, min effectivity)``
(:func:`safety_factor`). :func:`snapshot_count` decides the number of full-order training
steps: it runs the full model in chunks and stops once a fit on the earlier chunks predicts the
newest one well within the tolerance.

**Safety factor** (:func:`calibrate`, :func:`safety_factor`). The error ROM is an approximation,
not a bound: its raw effectivity (estimate / true error) was 0.92-1.32 on the 24 cases of
``benchmarks/rom_indicator.py``. The estimate ``reduce`` reports is the raw one times
``κ = 1.5 / min(1, min η)``, where ``η`` are raw effectivities measured on the training data
only: the same fit on the first half of the training window (DMD: the first two thirds)
predicting the first training runs (at most three, the nominal one first) over the whole window,
whose second half it has not seen — the true error is known there from the training snapshots.
The margin 1.5 is fixed: it keeps the calibrated estimate above the true error as long as the
raw effectivity on a new configuration is no more than a third below the worst calibration one,
and below 3x the true error while it is no more than twice the best. Calibrated, the 24 cases
gave effectivities 1.47-2.01 (1.44-2.00 for the maximum over time) — never below 1, never above 3.
The calibration costs one refit and up to three estimates on training-length
runs (offline data, no new full-order run).

**Snapshot rule** (the source chose the number of snapshots by eye, §8.1):
:func:`snapshot_count` grows the training window in chunks, refits after each, and stops when the
model fitted on everything *before* the newest chunk predicts that chunk within
``safety × tol`` — the model has stopped learning anything new from more full-order steps.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from ..state import initial_state
from ..timeloop import RunOptions
from .error_estimate import error_rom
from .metrics import rmse
from .snapshots import collect_first_order, tracer_operator

SAFETY_MARGIN = 1.5  # the calibrated estimate's margin over the worst effectivity seen in training


def safety_factor(effectivities, margin: float = SAFETY_MARGIN) -> float:
    """The factor applied to :func:`error_rom`'s estimate: ``margin / min(1, min η)`` over the
    calibration effectivities ``η = estimate / true error`` (training data only; non-finite
    ones — a calibration case without error — are ignored)."""
    eta = np.atleast_1d(np.asarray(effectivities, float))
    eta = eta[np.isfinite(eta) & (eta > 0)]
    return float(margin / min(1.0, float(eta.min()))) if eta.size else float(margin)


@dataclasses.dataclass(frozen=True)
class CalibrationCase:
    """One case of :func:`calibrate`: ``true_um`` the true tracer RMSE, µm, ``estimate_um`` the raw
    :func:`error_rom` estimate of it, ``effectivity`` their ratio (``nan`` for a case without
    error)."""

    true_um: float
    estimate_um: float
    effectivity: float


@dataclasses.dataclass(frozen=True)
class Calibration:
    """:func:`calibrate`'s result: the ``safety_factor`` and the ``cases`` it came from."""

    safety_factor: float
    cases: tuple[CalibrationCase, ...]


def calibrate(cases, dt, margin: float = SAFETY_MARGIN, **kwargs) -> Calibration:
    """Safety factor of :func:`error_rom` from cases whose true error is known from training data.

    ``cases``: iterable of ``(model, truth, prediction, trajectory, solver)`` — the observed
    tracers of the full model and of a reduced model fitted on part of the training data (each
    (n, o), m), that prediction as a :class:`~jaxbelt.rom.error_estimate.BasisTrajectory`, and the
    full model's solver for it (``None``: :func:`error_rom`'s default); ``dt`` the time step;
    ``kwargs``: further :func:`error_rom` arguments (``stride``, ``order``, ``options``, …).
    """
    rows = []
    for model, truth, pred, traj, solver in cases:
        true_um = float(rmse(jnp.asarray(truth), jnp.asarray(pred))) * 1e6
        est_um = error_rom(model, traj.basis, traj.coords, dt, traj.z_true0, solver=solver, **kwargs).rmse_um
        # a case without error (the reduced model reproduces its training run) says nothing
        eta = est_um / true_um if true_um > 1e-9 else float("nan")
        rows.append(CalibrationCase(true_um=true_um, estimate_um=est_um, effectivity=eta))
    return Calibration(safety_factor=safety_factor([r.effectivity for r in rows], margin), cases=tuple(rows))


@dataclasses.dataclass(frozen=True)
class SnapshotCount:
    """:func:`snapshot_count`'s result: ``n_steps`` the chosen count; ``converged`` whether the
    rule fired before ``max_steps``; ``history`` the validation errors ``[(m, rmse_um), …]``
    (training steps, tracer RMSE of the newest chunk's prediction in µm);
    ``Z`` the post-transport snapshots (2N, n_steps + 1)."""

    n_steps: int
    converged: bool
    history: list
    Z: jax.Array


def snapshot_count(model, fit_predict, options: RunOptions, tol_um: float = 20.0, chunk: int = 50,
                   safety: float = 0.1, min_chunks: int = 2) -> SnapshotCount:
    """Number of full-order steps worth training on, decided from the data, at most
    ``options.n_steps`` (steps of ``options.dt`` with ``options.solver``).

    Runs the full model ``chunk`` steps at a time. After each chunk ``k ≥ min_chunks`` it calls
    ``fit_predict(Z_train, n) -> tracer_u (n, n_tr)`` with the post-transport snapshots up to
    the previous chunk (2N, m) and compares the prediction of the newest ``chunk`` steps with the
    full model's tracers. Stops at the first chunk predicted within ``safety × tol_um`` (tracer
    RMSE, µm).
    """
    chunk_options = options.replace(n_steps=int(chunk))
    max_steps = int(options.n_steps)
    C = tracer_operator(model)
    N = model.n_unknowns
    state = initial_state(model)
    Z = None
    history = []
    while True:
        state, _, Zc = collect_first_order(model, chunk_options, state)
        Zc = Zc if Z is None else Zc[:, 1:]  # the start state is the previous chunk's end
        if Z is not None and Z.shape[1] >= min_chunks * chunk:
            truth = (C @ Zc[:N]).T
            err = float(rmse(truth, fit_predict(Z, Zc.shape[1]))) * 1e6
            history.append((int(Z.shape[1] - 1), err))
            if err < safety * tol_um:
                return SnapshotCount(n_steps=int(Z.shape[1] - 1), converged=True, history=history, Z=Z)
        Z = Zc if Z is None else jnp.concatenate([Z, Zc], axis=1)
        if Z.shape[1] - 1 >= max_steps:
            return SnapshotCount(n_steps=int(Z.shape[1] - 1), converged=False, history=history, Z=Z)
