"""One DMD-with-control model over a box of misalignments, trained only as much as the question
needs (``jaxbelt reduce --method dmdc --train-ranges``).

**The question.** A designer asks for a reduced model whose tracer error stays below a tolerance
``tol`` (the source's 20 µm by default) for *any* configuration in the box, over the horizon
they will predict. Training more than that costs full-order runs and a larger fit for accuracy
nobody asked for.

**The sizing loop** (:func:`train_over_box`). The training configurations are the axial design
(:func:`~jaxbelt.rom.training.axial_design`: the aligned machine and each component at ± its
half-width). The loop walks :data:`SCHEDULE`, a list of (training steps per run, modes) pairs. At
each level it:

1. continues every training run to the level's step count from where the last level stopped
   (only the new steps are run);
2. fits DMDc (:func:`~jaxbelt.rom.dmdc.fit_dmdc`) on a POD basis of all training snapshots from a
   randomized range finder with subspace iterations
   (:func:`~jaxbelt.rom.dmd.randomized_svd`; ``O(N m k)`` against the thin SVD's ``O(N m²)``);
3. estimates the tracer RMSE of ``held_out`` configurations drawn uniformly from the box, each
   over the whole horizon (:func:`~jaxbelt.rom.error_estimate.error_rom` × a safety factor). No
   full-order run of them is made;
4. where they all pass, calibrates the safety factor on the training data
   (:func:`~jaxbelt.rom.calibration.calibrate`: the same fit on the first half of the window
   predicting the first training runs over all of it) and checks them again with it. Until
   then the factor is :data:`~jaxbelt.rom.calibration.SAFETY_MARGIN`, the least any calibration
   gives: a level that fails with it would fail calibrated too, and the calibration (a refit and
   three estimates) is spent only on a level that may pass.

It stops at the first level where every held-out estimate is below ``target_fraction × tol``
(a tenth by default). The held-out configurations are estimated in turn, and a level is left at
its first held-out estimate above the target, so a level that fails costs one estimate. It also
stops, unconverged, when a level's estimate of the first held-out configuration is not below
:data:`STALL` times the previous level's (more training has stopped paying: what is left is the
floor of a linear model over this box), and when the training window reaches the horizon; it
then returns the level with the lowest estimate of the first held-out configuration (the one
estimated at every level), calibrated on its own window. The
training runs advance in chunks of the greatest common divisor of the levels' step counts, so
every level reuses one compiled run.

**Decision (not in the source).** The levels grow the training window and the modes together,
because a longer window brings new dynamics only a larger basis can hold. The design stays
axial: the belt's response is affine in small misalignments, so more configurations add nothing
the axial runs do not span. What more training cannot fix — the second-order lever arm of large
tilts — the held-out estimates see and report.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time

import jax
import jax.numpy as jnp
import numpy as np

from ..misalignment import aligned, apply
from ..state import initial_state
from ..timeloop import RunOptions
from .calibration import SAFETY_MARGIN, Calibration, calibrate
from .dmd import randomized_svd
from .dmdc import DMDcModel, belt_inputs, calibration_cases, fit_dmdc_in_basis, prediction_trajectory, stack_controlled
from .error_estimate import ErrorRomOptions, error_rom
from .pod_step import parameters
from .reduced_model import CALIBRATION_RUNS
from .snapshots import collect_first_order, state_to_z
from .training import axial_design

SCHEDULE = ((50, 20), (100, 30), (200, 40), (400, 60), (800, 80))  # (training steps per run, modes)
STALL = 0.7  # a level whose first held-out estimate is not below this fraction of the last one's stalls
OVERSAMPLING = 20  # sketch columns beyond the modes kept
POWER_ITERATIONS = 2  # subspace iterations of the range finder


@dataclasses.dataclass(frozen=True)
class SizingLevel:
    """One level of the sizing loop: ``train_steps`` per training run, ``modes``, the
    ``safety_factor`` applied (module docstring, step 3), the held-out estimates ``estimate_um``
    (tracer RMSE over the horizon times that factor, µm; only those evaluated before the level
    failed), whether it ``passed``, and the loop's cumulative ``seconds`` at its end."""

    train_steps: int
    modes: int
    safety_factor: float
    estimate_um: tuple[float, ...]
    passed: bool
    seconds: float


@dataclasses.dataclass(frozen=True)
class BoxTraining:
    """:func:`train_over_box`'s result.

    **Fields:** ``fit`` the DMDc model of the last level; ``models`` the training configurations
    (aligned first) and ``trajectories`` their post-transport snapshots (2N, train_steps + 1);
    ``chosen`` the index of the level whose model is returned (the last, unless the loop stopped
    unconverged: then the level with the lowest estimate of the first held-out configuration);
    ``thetas`` (2P + 1, P) their deviations, mm / mrad; ``labels`` the components;
    ``held_out`` (K, P) the held-out deviations; ``levels`` (:class:`SizingLevel`);
    ``converged`` whether a level met the target; ``stop`` why the loop stopped (``"met"``,
    ``"stalled"``: a level did not lower the estimate enough, ``"horizon"``: the window reached
    the horizon, ``"schedule"``: no larger level); ``target_um`` the target tracer RMSE, µm; ``seconds`` the whole
    loop (compilation included); ``calibration`` the error estimate's safety factor and its
    cases for the returned model (:func:`~jaxbelt.rom.calibration.calibrate`).
    """

    fit: DMDcModel
    models: tuple
    trajectories: tuple
    thetas: np.ndarray
    labels: tuple[str, ...]
    held_out: np.ndarray
    levels: tuple[SizingLevel, ...]
    chosen: int
    converged: bool
    stop: str
    target_um: float
    calibration: Calibration
    seconds: float

    @property
    def train_steps(self) -> int:
        return self.levels[self.chosen].train_steps

    @property
    def modes(self) -> int:
        return int(self.fit.A.shape[0])

    @property
    def safety_factor(self) -> float:
        return self.levels[self.chosen].safety_factor


def held_out_configurations(half_widths, count: int, seed: int = 0) -> np.ndarray:
    """``count`` deviations (count, P) drawn uniformly from the box ``|θ_k| ≤ h_k``."""
    h = np.asarray(half_widths, float)
    return np.random.default_rng(seed).uniform(-h, h, size=(int(count), h.size))


@functools.partial(jax.jit, static_argnums=2)
def fit_over_trajectories(trajectories, inputs, modes: int) -> DMDcModel:
    """DMDc on the training ``trajectories`` (each (2N, m + 1)) with their constant ``inputs``
    (each (l,)), in a POD basis of all their snapshots from a randomized range finder
    (``modes`` + :data:`OVERSAMPLING` columns, :data:`POWER_ITERATIONS` subspace iterations);
    one compiled program per shape."""
    Z = jnp.concatenate(list(trajectories), axis=1)
    k = min(int(modes) + OVERSAMPLING, *Z.shape)
    U, _, _ = randomized_svd(Z, k, POWER_ITERATIONS)
    X, Y, Ui = stack_controlled(trajectories, [belt_inputs(u, t.shape[1] - 1) for u, t in zip(inputs, trajectories)])
    return fit_dmdc_in_basis(U[:, : min(int(modes), k)], X, Y, Ui)


def train_over_box(nominal, components, half_widths, options: RunOptions, *,
                   tol_um: float = 20.0, target_fraction: float = 0.1, held_out: int = 10, seed: int = 0,
                   stride: int = 10, schedule=SCHEDULE, estimate: ErrorRomOptions = ErrorRomOptions(),
                   progress=None) -> BoxTraining:
    """Train DMDc over the box ``|θ_k| ≤ h_k`` around the aligned ``nominal`` until the error
    estimate on held-out configurations is below ``target_fraction × tol_um`` (tracer
    RMSE, µm; module docstring).

    **Arguments:** ``components`` labels ``"roller:component"``; ``half_widths`` (P,) mm / mrad;
    ``options`` the full model's run: ``n_steps`` the horizon the model must predict, ``dt`` the
    time step (s) and the ``solver`` (training runs and estimates); ``held_out`` how many configurations the
    estimate is checked on (at least 1), drawn with ``seed``; ``stride`` the estimate's residual
    windows and ``estimate`` its tuning; ``schedule`` the levels ((steps, modes), …, increasing); ``progress`` an optional
    callable given each :class:`SizingLevel`.
    **Returns:** :class:`BoxTraining` (``converged=False`` when no level met the target: the model
    of the level with the lowest estimate, ``chosen``, with its own calibrated factor).
    """
    if held_out < 1:
        raise ValueError(f"held_out = {held_out}: need at least one held-out configuration")
    if not schedule or any(s < 2 or r < 1 for s, r in schedule):
        raise ValueError(f"schedule = {schedule}: need (steps ≥ 2, modes ≥ 1) levels")
    t0 = time.perf_counter()
    n_steps, solver = int(options.n_steps), options.solver
    target = float(target_fraction) * float(tol_um)
    models, thetas, space = axial_design(nominal, components, half_widths)
    base = aligned(nominal)
    inputs = [parameters(m) for m in models]
    dt = jnp.asarray(options.dt, nominal.ell.dtype)
    states = [initial_state(m) for m in models]
    trajs = [None] * len(models)
    held = held_out_configurations(half_widths, held_out, seed)
    held_models = [apply(base, space, th, base=base.chi_static) for th in held]
    held_starts = [None] * len(held_models)
    chunk = functools.reduce(math.gcd, [int(s) for s, _ in schedule])
    chunk_options = RunOptions(solver, chunk, dt)
    levels, fits, done = [], [], 0
    fit = calibration = None
    for steps, modes in schedule:
        kappa = SAFETY_MARGIN  # a lower bound of this level's calibrated factor
        steps = min(int(steps), int(n_steps))
        while done < steps:
            for i, (m, st) in enumerate(zip(models, states)):
                states[i], _, Z = collect_first_order(m, chunk_options, st)
                trajs[i] = Z if trajs[i] is None else jnp.concatenate([trajs[i], Z[:, 1:]], axis=1)
            done += chunk
        steps = done
        fit = fit_over_trajectories(trajs, inputs, modes)
        fits.append((fit, steps, modes))

        raw = []
        for j, hm in enumerate(held_models):
            if held_starts[j] is None:  # the held-out start and input, computed the first time they are estimated
                held_starts[j] = (state_to_z(hm, initial_state(hm), dt), belt_inputs(parameters(hm), 1)[:, 0])
            traj = prediction_trajectory(fit, *held_starts[j], n_steps)
            raw.append(error_rom(hm, traj.basis, traj.coords, dt, traj.z_true0, stride=stride, order="post",
                                 solver=solver, options=estimate).rmse_um)
            if kappa * raw[-1] >= target:
                break
        passed = len(raw) == len(held_models) and kappa * max(raw) < target
        if passed:  # with the lower bound: calibrate this level and check again
            calibration = _calibration(models, trajs, inputs, modes, steps, dt, solver, stride, estimate)
            kappa = calibration.safety_factor
            passed = kappa * max(raw) < target
        level = SizingLevel(train_steps=steps, modes=int(fit.A.shape[0]), safety_factor=kappa,
                            estimate_um=tuple(float(kappa * e) for e in raw), passed=passed,
                            seconds=time.perf_counter() - t0)
        levels.append(level)
        if progress is not None:
            progress(level)
        stalled = len(levels) > 1 and raw[0] > STALL * levels[-2].estimate_um[0] / levels[-2].safety_factor
        stop = "met" if passed else "stalled" if stalled else "horizon" if steps >= n_steps else None
        if stop:
            break
    else:
        stop = "schedule"
    chosen = len(levels) - 1
    if not levels[-1].passed:
        # the level whose estimate of the first held-out configuration (estimated at every level) is
        # the lowest, with its own window of the runs and its own calibrated factor
        chosen = int(np.argmin([lv.estimate_um[0] / lv.safety_factor for lv in levels]))
        fit, steps, modes = fits[chosen]
        trajs = [Z[:, : steps + 1] for Z in trajs]
        calibration = _calibration(models, trajs, inputs, modes, steps, dt, solver, stride, estimate)
        lv = levels[chosen]
        scale = calibration.safety_factor / lv.safety_factor
        levels[chosen] = dataclasses.replace(lv, safety_factor=calibration.safety_factor,
                                             estimate_um=tuple(e * scale for e in lv.estimate_um))
    return BoxTraining(fit=fit, models=tuple(models), trajectories=tuple(trajs), thetas=thetas,
                       labels=tuple(space.labels()), held_out=held, levels=tuple(levels), chosen=chosen,
                       converged=levels[chosen].passed, stop=stop, target_um=target, calibration=calibration,
                       seconds=time.perf_counter() - t0)


def _calibration(models, trajs, inputs, modes, steps, dt, solver, stride, options) -> Calibration:
    """The error estimate's safety factor from the training data: DMDc fitted on the first half
    of the window predicts the first :data:`~jaxbelt.rom.reduced_model.CALIBRATION_RUNS` training runs
    over all of it (:func:`~jaxbelt.rom.calibration.calibrate`)."""
    cfit = fit_over_trajectories([Z[:, : max(1, steps // 2) + 1] for Z in trajs], inputs, modes)
    runs = [(m, Z, mu, solver) for m, Z, mu in zip(models, trajs, inputs)][:CALIBRATION_RUNS]
    return calibrate(calibration_cases(cfit, runs, steps), dt, stride=stride, order="post", options=options)


__all__ = ["SCHEDULE", "SizingLevel", "BoxTraining", "train_over_box", "held_out_configurations",
           "fit_over_trajectories"]
