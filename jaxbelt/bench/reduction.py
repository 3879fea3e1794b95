"""What ``jaxbelt reduce`` reports a reduced model costs against the full model: the full runs
timed in the scene's solver mode and in its reuse mode (frozen factors, :class:`jaxbelt.Reuse`),
the training runs put in the faster of the two where it reproduces the other
(:data:`REUSE_MATCH_UM`), and the speedups (:func:`reduce_and_time`).

Times exclude compilation on both sides (the first calls, compilation included, are reported
apart): offline = snapshot runs (in the fastest full mode) + fit, online = the reduced
prediction, each by :func:`~jaxbelt.bench.timing.warm_best`. Every speedup is against that
fastest full mode; ``speedup_eq_7_5`` is the source's step-count formula ``n / (n_train +
n_predicted / s)``, ``s`` the per-step online speedup.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..infra.results import Result, to_json
from ..integrators import solver_name
from ..rom.comparison import FullRunDivergedError, ReductionResult
from ..rom.config import ReduceConfig
from ..rom.pipeline import full_run, is_reuse, reduce_and_compare, reuse_mode
from ..timeloop import SaveAt, compile_simulate
from .timing import warm_best

REUSE_MATCH_UM = 1e-3  # the reuse mode replaces the given one only if it reproduces its tracers this closely


@dataclasses.dataclass(frozen=True)
class FullModeTime(Result):
    """One full run timed: its solver ``mode`` (:func:`jaxbelt.integrators.solver_name`) and
    ``run_s`` its seconds, compilation excluded."""

    mode: str
    run_s: float


@dataclasses.dataclass(frozen=True)
class ReductionTimings(Result):
    """Seconds, compilation excluded (``offline_first_call_s`` includes it), and the speedups
    (module docstring). ``full_runs``: every full mode timed; ``full_mode`` the fastest one that
    reproduces the given solver's; ``scene_mode_run_s`` the given solver's; ``error_estimate_s``
    the error estimate of the prediction, ``error_estimate_total_s`` with the calibration of its
    safety factor, one call each, compilation included (``None`` without an estimate)."""

    full_run_s: float
    full_mode: str
    full_runs: tuple[FullModeTime, ...]
    scene_mode_run_s: float
    offline_s: float
    offline_first_call_s: float
    online_s: float
    speedup_online: float
    speedup_total: float
    speedup_total_vs_scene_mode: float
    speedup_per_step_online: float
    speedup_eq_7_5: float
    error_estimate_s: float | None = None
    error_estimate_total_s: float | None = None
    note: str = ("compilation excluded on both sides; speedups against the fastest full mode reproducing the "
                 "scene's own to 1e-3 µm; eq. 7.5 is the source's step-count formula")


@dataclasses.dataclass(frozen=True)
class TimedReduction(Result):
    """:func:`reduce_and_time`'s result: the comparison (:class:`~jaxbelt.rom.ReductionResult`)
    and what it cost against the full model (:class:`ReductionTimings`)."""

    result: ReductionResult
    timings: ReductionTimings

    def to_dict(self) -> dict:
        """The comparison's fields (:meth:`~jaxbelt.rom.ReductionResult.to_dict`) with ``timings``."""
        return dict(self.result.to_dict(), timings=to_json(self.timings))


def full_runs(model, solver, config: ReduceConfig):
    """``(trajectory, (FullModeTime, …), reuse_factors)``: the full run in ``solver``'s mode and,
    unless that is the reuse mode already, in the reuse mode, each timed after its compilation;
    ``reuse_factors`` whether the reuse mode is the faster and reproduces the given mode's tracers
    to :data:`REUSE_MATCH_UM`."""

    def run(s):
        return lambda: full_run(model, s, config)

    traj, own_s, _ = warm_best(run(solver), repeat=3, budget_s=1.0)
    if not np.all(np.isfinite(np.asarray(traj.tracer_u))):
        raise FullRunDivergedError("the full simulation diverged; nothing to compare with")
    times = [FullModeTime(solver_name(solver), own_s)]
    if is_reuse(solver):
        return traj, tuple(times), False
    reuse = reuse_mode(solver)
    traj_r, reuse_s, _ = warm_best(run(reuse), repeat=3, budget_s=1.0)
    times.append(FullModeTime(solver_name(reuse), reuse_s))
    dev_um = 1e6 * max(float(np.max(np.abs(np.asarray(traj_r.tracer_u) - np.asarray(traj.tracer_u)))),
                       float(np.max(np.abs(np.asarray(traj_r.tracer_u_solved) - np.asarray(traj.tracer_u_solved)))))
    return traj, tuple(times), bool(dev_um <= REUSE_MATCH_UM and reuse_s < own_s)


def warm_full_runs(model, solver, config: ReduceConfig):
    """Compile, without running them, the full runs :func:`reduce_and_time` times: in
    ``solver``'s mode and, unless that is it already, in the reuse mode (the same arguments as
    there, so the timed calls find the compiled programs; :func:`jaxbelt.timeloop.compile_simulate`).
    A caller with other work to do first — the sized training of ``jaxbelt reduce --train-ranges``
    — runs this in a background thread and overlaps the compilation with that work."""
    o = config.options
    for s in dict.fromkeys((solver, reuse_mode(solver))):
        compile_simulate(model, s, n_steps=int(o.n_steps), dt=o.dt, saveat=SaveAt(every=o.saveat.every))


def reduce_and_time(model, train, config: ReduceConfig, train_solvers=None, trained=None) -> TimedReduction:
    """:func:`~jaxbelt.rom.reduce_and_compare` with its costs measured: the full runs timed
    (:func:`full_runs`), the training runs in the fastest full mode, offline and online times
    by :func:`~jaxbelt.bench.timing.warm_best`, and the speedups (module docstring)."""
    solver = config.options.solver
    traj, times, reuse_factors = full_runs(model, solver, config)
    result = reduce_and_compare(model, train, config, train_solvers, trained, full_trajectory=traj,
                                reuse_factors=reuse_factors, clock=warm_best)
    n, start, cost = result.n_steps, result.predict_from_step, result.cost
    fastest = times[-1] if reuse_factors else times[0]
    scene_s = times[0].run_s
    per_step = (fastest.run_s / n) / (cost.online_s / max(n - start, 1))
    total = cost.offline_s + cost.online_s
    timings = ReductionTimings(
        full_run_s=fastest.run_s, full_mode=fastest.mode, full_runs=times, scene_mode_run_s=scene_s,
        offline_s=cost.offline_s, offline_first_call_s=cost.offline_first_call_s, online_s=cost.online_s,
        speedup_online=fastest.run_s / cost.online_s, speedup_total=fastest.run_s / total,
        speedup_total_vs_scene_mode=scene_s / total, speedup_per_step_online=per_step,
        speedup_eq_7_5=n / (result.train_steps * result.n_train_runs + (n - start) / per_step),
        error_estimate_s=cost.estimate_s,
        error_estimate_total_s=None if cost.estimate_s is None else cost.estimate_s + cost.calibration_s)
    return TimedReduction(result=result, timings=timings)
