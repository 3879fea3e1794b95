"""The report of :func:`jaxbelt.rom.reduce_and_compare`: :class:`ReductionResult` (the reduced
model's error against the full model, the estimate of that error, and what it cost)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..infra.results import Result, to_json
from .calibration import CalibrationCase
from .error_estimate import EstimateCost
from .reduced_model import AbstractReduction, Spectra


class FullRunDivergedError(FloatingPointError):
    """The full-order run of the predicted configuration diverged: nothing to compare with."""


class ReducedRunDivergedError(FloatingPointError):
    """The reduced model's prediction is not finite (its projected step is unstable)."""


@dataclasses.dataclass(frozen=True)
class ReductionCost(Result):
    """What the reduced model cost, s, compilation excluded (``offline_first_call_s`` includes
    it): ``offline_s`` the training runs and the fit, ``online_s`` the prediction;
    ``estimate_s`` the error estimate of the prediction and ``calibration_s`` the calibration of
    its safety factor (0 where a sized training's is taken), each one call, compilation included
    (``None`` without an estimate)."""

    offline_s: float
    offline_first_call_s: float
    online_s: float
    estimate_s: float | None = None
    calibration_s: float | None = None


@dataclasses.dataclass(frozen=True)
class ReductionEstimate(Result):
    """The calibrated error estimate of a prediction.

    **Fields:** ``error_um`` (k,) the estimated tracer RMSE at each compared step, µm;
    ``rmse_um`` / ``max_um`` its rms and maximum over them (``None`` without compared steps);
    ``raw_rmse_um`` the same before the safety factor; ``safety_factor`` and the
    ``calibration`` cases it came from; ``subspace_dim``, ``projected_spectral_radius`` and
    ``cost`` of the error ROM; ``full_steps_predicted`` the full steps the estimate replaces
    (its seconds: :class:`ReductionCost`).
    """

    error_um: np.ndarray
    rmse_um: float | None
    max_um: float | None
    raw_rmse_um: float | None
    safety_factor: float
    calibration: tuple[CalibrationCase, ...]
    subspace_dim: int
    projected_spectral_radius: float
    cost: EstimateCost
    full_steps_predicted: int


@dataclasses.dataclass(frozen=True)
class ReductionResult(Result):
    """:func:`reduce_and_compare`'s result. Tracer errors in µm, times in s.

    **Fields:** ``method`` the reduction; ``modes`` the reduced dimension used;
    ``modes_discarded`` (dmd: the unstable modes dropped, else ``None``);
    ``training_starts_at_step`` (pdmd: the first snapshot of its per-configuration trajectories,
    else ``None``); ``train_steps`` per training run; ``n_train_runs``; ``n_steps``;
    ``predict_from_step`` (the prediction covers steps ``predict_from_step + 1 … n_steps``);
    ``compared`` the trajectory field compared (``"tracer_u"``, or ``"tracer_u_solved"`` for
    dmd's pre-transport states); ``n_unknowns``, ``n_tracers``; ``rmse_um``, ``rrmse`` and
    ``max_rmse_over_time_um`` (``None`` without compared steps) of the prediction; ``t`` (k,) the
    compared steps' times, s, and ``error_um`` (k,) the tracer RMSE at each; ``estimate``
    (:class:`ReductionEstimate`, ``None`` with ``stride = 0``); ``cost``
    (:class:`ReductionCost`, ``None`` where nothing was timed); ``spectra``
    (:class:`~jaxbelt.rom.reduced_model.Spectra`, where asked for); ``sizing`` the sizing loop's
    levels (:class:`~jaxbelt.rom.sizing.SizingLevel`) where the training was sized to a tolerance
    (:func:`~jaxbelt.rom.sizing.train_over_box`), else ``None``.
    """

    method: AbstractReduction
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
    rmse_um: float
    rrmse: float
    max_rmse_over_time_um: float | None
    t: np.ndarray
    error_um: np.ndarray
    estimate: ReductionEstimate | None
    cost: ReductionCost | None
    spectra: Spectra | None
    sizing: tuple | None = None

    @property
    def predict_steps(self) -> int:
        return self.n_steps - self.predict_from_step

    @property
    def effectivity(self) -> float | None:
        """Estimated over true tracer RMSE (``None`` without an estimate, or where the true error is
        zero: no ratio, as in the calibration's cases)."""
        if self.estimate is None or self.estimate.rmse_um is None or self.rmse_um == 0:
            return None
        return self.estimate.rmse_um / self.rmse_um

    def to_dict(self) -> dict:
        """JSON-able data (:mod:`jaxbelt.infra.results`): the fields, ``method`` by its name."""
        return to_json(dict(dataclasses.asdict(self), method=self.method.name, predict_steps=self.predict_steps,
                            effectivity=self.effectivity))
