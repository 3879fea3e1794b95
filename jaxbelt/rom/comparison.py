"""The report of :func:`jaxbelt.rom.reduce_and_compare`: :class:`ReductionResult` (the reduced
model's error against the full model, the estimate of that error, and what it cost)."""

from __future__ import annotations

import dataclasses

import numpy as np

from .calibration import CalibrationCase
from .error_estimate import EstimateCost


class FullRunDivergedError(FloatingPointError):
    """The full-order run of the predicted configuration diverged: nothing to compare with."""


class ReducedRunDivergedError(FloatingPointError):
    """The reduced model's prediction is not finite (its projected step is unstable)."""


@dataclasses.dataclass(frozen=True)
class Timings:
    """Seconds, compilation excluded (``offline_first_call_s`` includes it), and the speedups
    (module docstring). ``full_runs_s``: every full mode timed, by solver name; ``full_mode`` the
    fastest one that reproduces the given solver's; ``scene_mode_run_s`` the given solver's."""

    full_run_s: float
    full_mode: str
    full_runs_s: dict
    scene_mode_run_s: float
    offline_s: float
    offline_first_call_s: float
    online_s: float
    speedup_online: float
    speedup_total: float
    speedup_total_vs_scene_mode: float
    speedup_per_step_online: float
    speedup_eq_7_5: float
    note: str = ("compilation excluded on both sides; speedups against the fastest full mode reproducing the "
                 "scene's own to 1e-6 mm; eq. 7.5 is the source's step-count formula")


@dataclasses.dataclass(frozen=True)
class ReductionEstimate:
    """The calibrated error estimate of a prediction.

    **Fields:** ``error_mm`` (k,) the estimated tracer RMSE at each compared step, mm;
    ``rmse_mm`` / ``max_mm`` its rms and maximum over them (``None`` without compared steps);
    ``raw_rmse_mm`` the same before the safety factor; ``safety_factor`` and the
    ``calibration`` cases it came from; ``subspace_dim``, ``projected_spectral_radius`` and
    ``cost`` of the error ROM; ``full_steps_predicted`` the full steps the estimate replaces;
    ``test_s`` the estimate's seconds, ``total_s`` with the calibration.
    """

    error_mm: np.ndarray
    rmse_mm: float | None
    max_mm: float | None
    raw_rmse_mm: float | None
    safety_factor: float
    calibration: tuple[CalibrationCase, ...]
    subspace_dim: int
    projected_spectral_radius: float
    cost: EstimateCost
    full_steps_predicted: int
    test_s: float
    total_s: float


@dataclasses.dataclass(frozen=True)
class Spectra:
    """What a plot of the fit shows: ``singular_values`` of the training snapshots, ``marked`` the
    number of modes to mark among them (``None``: the modes used), and for DMD-type methods the
    ``eigs`` with their ``eig_weights`` (the scaled mode norms)."""

    singular_values: np.ndarray
    marked: int | None = None
    eigs: np.ndarray | None = None
    eig_weights: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class ReductionResult:
    """:func:`reduce_and_compare`'s result. Errors in mm, times in s.

    **Fields:** ``method``; ``modes`` the reduced dimension used; ``modes_discarded`` (dmd: the
    unstable modes dropped, else ``None``); ``training_starts_at_step`` (pdmd: the first snapshot
    of its per-configuration trajectories, else ``None``); ``train_steps`` per training run;
    ``n_train_runs``; ``n_steps``; ``predict_from_step`` (the prediction covers steps
    ``predict_from_step + 1 … n_steps``); ``compared`` the trajectory field compared
    (``"tracer_u"``, or ``"tracer_u_solved"`` for dmd's pre-transport states); ``n_unknowns``,
    ``n_tracers``; ``rmse_mm``, ``rrmse`` and ``max_rmse_over_time_mm`` (``None`` without compared
    steps) of the prediction; ``t`` (k,) the compared steps' times and ``error_mm`` (k,) the tracer
    RMSE at each; ``estimate`` (:class:`ReductionEstimate`, ``None`` with ``stride = 0``);
    ``timings`` (:class:`Timings`); ``spectra`` (:class:`Spectra`, where asked for); ``sizing``
    the sizing loop's levels (:class:`~jaxbelt.rom.box.SizingLevel`) where the training was sized
    to a tolerance (:func:`~jaxbelt.rom.box.train_over_box`), else ``None``.
    """

    method: str
    modes: int
    modes_discarded: int | None
    training_starts_at_step: int | None
    train_steps: int
    n_train_runs: int
    n_steps: int
    predict_from_step: int
    compared: str
    n_unknowns: int
    n_tracers: int
    rmse_mm: float
    rrmse: float
    max_rmse_over_time_mm: float | None
    t: np.ndarray
    error_mm: np.ndarray
    estimate: ReductionEstimate | None
    timings: Timings
    spectra: Spectra | None
    sizing: tuple | None = None

    @property
    def predict_steps(self) -> int:
        return self.n_steps - self.predict_from_step

    @property
    def effectivity(self) -> float | None:
        """Estimated over true tracer RMSE (``None`` without an estimate)."""
        if self.estimate is None or self.estimate.rmse_mm is None:
            return None
        return self.estimate.rmse_mm / self.rmse_mm


