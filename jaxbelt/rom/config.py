"""The request of :func:`jaxbelt.rom.reduce_and_compare`: :class:`ReduceConfig` (which reduced
model, how many modes, what to estimate)."""

from __future__ import annotations

import dataclasses

from ..integrators import AbstractIntegrator, make_solver
from .error_estimate import ErrorRomOptions

METHODS = ("pod", "dmd", "dmdc", "pdmd")
DEFAULT_MODES = {"pod": 20, "dmd": None, "dmdc": 30, "pdmd": 30}
CALIBRATION_RUNS = 3  # training runs the error estimate's safety factor is calibrated on



@dataclasses.dataclass(frozen=True)
class ReduceConfig:
    """Options of :func:`reduce_and_compare`.

    **Fields:** ``method`` one of :data:`METHODS`; ``n_steps`` steps to predict and compare;
    ``dt`` the time step, s; ``solver`` the full model's integrator (default
    :func:`jaxbelt.make_solver`'s); ``every`` the full run's record interval (the comparison is at
    its recorded steps); ``train_steps`` full-order steps per training configuration (default
    ``min(200, n_steps // 2)``); ``modes`` the reduced dimension (default
    :data:`DEFAULT_MODES`; dmd: all non-negligible); ``stride`` the error estimate's residual
    windows (0: no estimate); ``estimate`` the error ROM's tuning; ``calibration_runs`` training
    runs the safety factor is calibrated on; ``spectra`` whether to keep the singular values and
    eigenvalues of the fit (:class:`Spectra`, for a plot).
    """

    method: str
    n_steps: int
    dt: float
    solver: AbstractIntegrator | None = None
    every: int = 1
    train_steps: int | None = None
    modes: int | None = None
    stride: int = 10
    estimate: ErrorRomOptions = ErrorRomOptions()
    calibration_runs: int = CALIBRATION_RUNS
    spectra: bool = False

    def __post_init__(self):
        if self.method not in METHODS:
            raise ValueError(f"method = {self.method!r}: one of {', '.join(METHODS)}")
        for name, low in (("n_steps", 1), ("every", 1), ("stride", 0), ("calibration_runs", 0)):
            if int(getattr(self, name)) < low:
                raise ValueError(f"{name} = {getattr(self, name)}: must be at least {low}")
        if self.modes is not None and self.modes < 1:
            raise ValueError(f"modes = {self.modes}: must be at least 1")
        low = 2 if self.method == "dmd" else 1
        if self.train_window < low:
            raise ValueError(f"n_steps = {self.n_steps}, train_steps = {self.train_window}: too few steps to train on "
                             f"(at least {low})")
        if self.method == "dmd" and self.train_window >= self.n_steps:
            raise ValueError(f"train_steps = {self.train_window} with n_steps = {self.n_steps}: dmd predicts the steps "
                             "after the training window, so train_steps must be smaller than n_steps")

    @property
    def train_window(self) -> int:
        """Full-order steps per training configuration."""
        return int(self.train_steps or min(200, self.n_steps // 2))

    @property
    def n_modes(self) -> int | None:
        """The reduced dimension asked for (``None``: dmd's every non-negligible one)."""
        return DEFAULT_MODES[self.method] if self.modes is None else int(self.modes)

    @property
    def full_solver(self) -> AbstractIntegrator:
        return make_solver() if self.solver is None else self.solver
