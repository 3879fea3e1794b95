"""The request of :func:`jaxbelt.rom.reduce_and_compare`: :class:`ReduceConfig` (which reduced
model, over how many steps, what to estimate)."""

from __future__ import annotations

import dataclasses

from ..timeloop import RunOptions
from .error_estimate import ErrorRomOptions
from .reduced_model import CALIBRATION_RUNS, AbstractReduction


@dataclasses.dataclass(frozen=True)
class ReduceConfig:
    """Options of :func:`reduce_and_compare`.

    **Fields:** ``method`` the reduction and its modes (:class:`~jaxbelt.rom.ReducedPOD`,
    :class:`~jaxbelt.rom.DMD`, :class:`~jaxbelt.rom.DMDc`, :class:`~jaxbelt.rom.ParametricDMD`);
    ``options`` the full model's run (:class:`jaxbelt.RunOptions`): its ``n_steps`` the steps to
    predict and compare, its ``dt``, its ``solver``, its ``saveat.every`` the full run's record
    interval (the comparison is at its recorded steps); ``train_steps`` full-order steps per training
    configuration (default ``min(200, n_steps // 2)``); ``stride`` the error estimate's residual
    windows (0: no estimate); ``estimate`` the error ROM's tuning; ``calibration_runs`` training
    runs the safety factor is calibrated on; ``spectra`` whether to keep the singular values and
    eigenvalues of the fit (:class:`~jaxbelt.rom.reduced_model.Spectra`, for a plot).
    """

    method: AbstractReduction
    options: RunOptions
    train_steps: int | None = None
    stride: int = 10
    estimate: ErrorRomOptions = ErrorRomOptions()
    calibration_runs: int = CALIBRATION_RUNS
    spectra: bool = False

    def __post_init__(self):
        if not isinstance(self.method, AbstractReduction):
            raise ValueError(f"method = {self.method!r}: a reduction (ReducedPOD(), DMD(), DMDc(), ParametricDMD())")
        if not isinstance(self.options, RunOptions):
            raise ValueError(f"options = {self.options!r}: the full run's settings (jaxbelt.RunOptions)")
        for name, value, low in (("options.n_steps", self.options.n_steps, 1), ("stride", self.stride, 0),
                                 ("calibration_runs", self.calibration_runs, 0)):
            if int(value) < low:
                raise ValueError(f"{name} = {value}: must be at least {low}")
        self.method.check(int(self.options.n_steps), self.train_window)

    @property
    def train_window(self) -> int:
        """Full-order steps per training configuration."""
        return int(self.train_steps or min(200, self.options.n_steps // 2))
