"""The cheapest run that meets an accuracy: grid, model and precision.

**The grid** (:func:`choose_grid`): the estimate's per-direction errors and orders
(:func:`~jaxbelt.accuracy.estimate_error`) model the error of a grid refined by ``f_d`` as
``F_s Σ_d e_d f_d^(−p_d)``; the cost of a run as ``f_ξ f_η f_Δt`` times the scene's (a finer mesh
along the belt forcing ``f_Δt ≥ f_ξ × CFL``). The cheapest refinement whose modelled error meets
the accuracy is built, and its own estimate is computed — the choice is verified, not assumed;
where it misses, the choice is made again from the chosen grid's own estimate (three rounds at
most). A direction is coarsened no further than its ladder went: the error model is not
extrapolated to grids coarser than it saw. Before a grid runs, its cost is predicted — its cost
multiple times the run time of the grid estimated last, times the runs its own estimate needs
(:func:`verification_cost_s`) — and a grid that would take the choice over its budget
(``max_cost_s``, default :data:`DEFAULT_MAX_COST_S`, the time already spent included) is refused
with that prediction, before it runs. Where a refinement makes the estimate larger, the coarser
estimate was not in the asymptotic range, and a refusal says so. Where no grid
within memory is predicted to meet the accuracy, the best one is verified all the same and the
error model fitted again on it: a refusal quotes what was verified, not only a prediction.

**The start-up.** The error is taken over the output times from ``t_from`` on. A run from rest
(:func:`jaxbelt.initial_state`) starts with a transient that converges slowest of all — an idle
roller's undamped swing, damped only by Backward Euler (``docs/speed.md``) — so an accuracy asked
over the whole run is an accuracy on the start-up; ``t_from`` (``jaxbelt simulate --from``)
excludes it, and the design commands take their own windows.

**The model** (``allow_1d``): a 2D scene with nothing to push the belt sideways — no roller tilt,
no translation or force off the loop's plane, no steering loop, no lateral transport — has no
lateral displacement by symmetry, and its longitudinal answer is the 1D string model's up to the
in-plane physics the string lacks (plane stress, the rows across). The program then runs the 1D
counterpart (:func:`one_d_counterpart`) when it is cheaper and its answer stays within the
accuracy: the difference between the two models is *measured*, on the 2D scene's own grid over
the asked window, and added to the 1D grid's estimate; the 1D grid is chosen by the same
procedure (``benchmarks/model_choice.py`` measures the difference and the saving).

**The solver**: where the caller leaves the solver to the scene, the direct integrator's reuse
solver (the first step's factors, refined against the current matrix; exact to round-off with
the shift transport and no lateral transport) is run on the chosen grid beside the scene's own
solver and taken where the measured difference fits within the accuracy and it is faster. The
comparison is of single runs; an answer made of batches of runs (the design commands:
``allow_reuse=False``) keeps the scene's solver, since in a batch the exact solver's kept factors
are shared by every configuration and it is the faster one (``benchmarks/sweep_throughput.py``).

**The precision** (``allow_float32``): float32 is taken where its rounding leaves the answer within
the accuracy: the chosen grid is run in both precisions, the largest difference of the tracers
over the window (the float32 rounding, measured) is added to the discretisation estimate, and
float32 is chosen when that sum meets the accuracy and the float32 run is faster. A run in the
chosen precision is built and run inside :func:`precision_scope`. The design commands keep
float64: their Jacobians difference and differentiate the metric, where float32's rounding is not
what this check measures.
"""

from __future__ import annotations

import dataclasses
import math
import time

import jax
import numpy as np

from ..infra.results import to_json
from ..scene import Scene
from ..run_checks import NonFiniteStateError
from .estimate import (DIRECTIONS, DiscretisationError, TracerRun, admissible, at_times, estimate_error, refine,
                       scene_grid, tracer_run)

REFINEMENTS = tuple(2.0**k for k in range(-2, 9))  # candidate refinement factors per direction: 1/4 … 256
QUANTITIES = ("longitudinal", "lateral")
PRECISIONS = ("float64", "float32")
DEFAULT_MAX_COST_S = 300.0  # s: the budget of a choice, its runs and verifications together


class AccuracyError(ValueError):
    """No grid within the machine's memory reaches the accuracy asked for."""


@dataclasses.dataclass(frozen=True)
class ModelCheck:
    """A cheaper model measured against the chosen one (``1d`` for a symmetric 2D scene,
    ``float32`` for the precision).

    **Fields:** ``name``; ``difference_um`` the largest tracer difference over the window and the
    quantities asked (µm); ``run_s`` the cheaper model's run time and ``reference_run_s`` the
    run it would replace, on the same grid (s, compilation apart); ``used`` whether it was chosen; ``why`` in
    words."""

    name: str
    difference_um: float | None
    run_s: float | None
    reference_run_s: float | None
    used: bool
    why: str


@dataclasses.dataclass(frozen=True)
class GridChoice:
    """:func:`choose_grid`'s result.

    **Fields:** ``scene`` the scene to run (on the chosen grid; the 1D counterpart where chosen);
    ``grid`` its :class:`~jaxbelt.accuracy.Grid`; ``factors`` the refinement factors against the
    given scene's grid (of the scene that was refined), per direction; ``solver``, ``model``
    (``1d``/``2d``) and ``precision`` (``float64``/``float32``, see :func:`precision_scope`) the
    run's; ``estimate`` the chosen grid's own
    :class:`~jaxbelt.accuracy.DiscretisationError` (the verification); ``estimate_um`` its
    largest value over the ``quantities`` asked, plus the measured model and rounding differences
    of the substitutions taken; ``predicted_um`` what the error model predicted for the grid;
    ``cost_s`` the chosen run's wall time (compilation apart); ``accuracy_um`` the accuracy asked
    for; ``rounds`` the choices made until one was verified; ``checks`` the
    :class:`ModelCheck` of each substitution considered; ``automatic`` what the program decided
    itself, in words."""

    scene: Scene
    grid: object
    factors: dict
    solver: str
    precision: str
    estimate: DiscretisationError
    estimate_um: float
    predicted_um: float
    cost_s: float
    accuracy_um: float
    quantities: tuple[str, ...]
    rounds: int
    automatic: tuple[str, ...]
    model: str = "2d"
    checks: tuple[ModelCheck, ...] = ()

    def to_dict(self) -> dict:
        """The JSON form (``chosen`` of the commands' ``--accuracy-um``)."""
        return to_json(dict(n_xi=self.grid.n_xi, n_eta=self.grid.n_eta, dt_s=self.grid.dt, solver=self.solver,
                    model=self.model, precision=self.precision, estimate_um=self.estimate_um,
                    predicted_um=self.predicted_um, cost_s=self.cost_s, accuracy_um=self.accuracy_um,
                    quantities=list(self.quantities), factors=self.factors, rounds=self.rounds,
                    automatic=list(self.automatic), checks=[dataclasses.asdict(c) for c in self.checks],
                    discretisation_error_um=self.estimate.to_dict()))


def precision_scope(precision: str):
    """The context in which a model of ``precision`` is built and run: ``jax.enable_x64`` on for
    float64, off for float32 (JAX's arrays take their default precision from it)."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision = {precision!r}: one of {', '.join(PRECISIONS)}")
    return jax.enable_x64(precision == "float64")


def asked_value(est: DiscretisationError, quantities) -> float:
    """The estimate's largest value over the quantities asked (lateral skipped in 1D)."""
    vals = [est.longitudinal_um if q == "longitudinal" else est.lateral_um for q in quantities]
    vals = [v for v in vals if v is not None]
    return max(vals) if vals else 0.0


def window_difference_um(a: TracerRun, b: TracerRun, scene: Scene, quantities, t_from: float) -> float:
    """The largest tracer difference (µm) of two runs on ``scene``'s time grid, over the output
    times from ``t_from`` on and the quantities asked (a run without ``v`` counts as ``v = 0``)."""
    k = int(round(scene.time.t_end / scene.time.dt))
    ua, va = at_times(a, scene.time.dt, scene.time.dt, k, t_from)
    ub, vb = at_times(b, scene.time.dt, scene.time.dt, k, t_from)
    out = []
    if "longitudinal" in quantities:
        out.append(float(np.max(np.abs(ua - ub))))
    if "lateral" in quantities and (va is not None or vb is not None):
        out.append(float(np.max(np.abs((0.0 if va is None else va) - (0.0 if vb is None else vb)))))
    return 1e6 * max(out, default=0.0)


def one_d_counterpart(scene: Scene) -> tuple[Scene | None, str]:
    """``(scene_1d, why)``: the 1D string model of a 2D scene with nothing to push the belt
    sideways (model specification §2: per roller the x translation, forces along x), or
    ``(None, why not)``."""
    if scene.kind != "2d":
        return None, "the scene is 1D"
    why_not = []
    for r in scene.rollers:
        if r.translation[1] != 0.0 or r.translation[2] != 0.0:
            why_not.append(f"roller {r.name!r} translated off x")
        if any(a != 0.0 for a in r.rotation):
            why_not.append(f"roller {r.name!r} tilted")
        if r.force[1] != 0.0 or r.force[2] != 0.0 or any(t != 0.0 for t in r.torque):
            why_not.append(f"roller {r.name!r} loaded off x")
    if scene.control:
        why_not.append("a steering loop tilts a roller")
    if scene.solver.lateral_transport:
        why_not.append("lateral transport is on")
    if why_not:
        return None, "lateral physics: " + "; ".join(why_not)
    mesh = dataclasses.replace(scene.mesh, n_eta=1)
    return scene.replace(kind="1d", mesh=mesh, name=f"{scene.name} (1D counterpart)"), (
        "nothing pushes the belt sideways: no lateral displacement by symmetry")


def _error_model(est: DiscretisationError, quantities):
    """``f ↦ modelled error (µm)`` for refinement factors ``f = {direction: factor}`` from the
    estimate's per-direction errors and orders."""
    terms = []
    for d in est.directions:
        p = d.order if d.order is not None else 0.0
        for q in quantities:
            e = d.longitudinal_um if q == "longitudinal" else d.lateral_um
            if e is not None:
                terms.append((q, d.direction, e, p))

    def model(f):
        by_q = {}
        for q, direction, e, p in terms:
            by_q[q] = by_q.get(q, 0.0) + e * (f.get(direction, 1.0) ** -p if p > 0 else 1.0)
        return est.safety_factor * max(by_q.values(), default=0.0)

    return model


def _memory_limit_bytes() -> float:
    """Half the machine's physical memory (a run must leave room for the rest)."""
    try:
        import os

        return 0.5 * os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        return 8e9


def _candidates(scene: Scene, est: DiscretisationError, quantities, run_bytes: float):
    """Every refinement of the scene's grid as ``(cost multiple, modelled error µm, factors,
    scene on the refined mesh, fits in memory)``, cheapest first. A direction is coarsened no
    further than its ladder went (the error model is not extrapolated to coarser grids than it
    saw); a direction the scene lacks (``n_eta`` in 1D) stays."""
    model = _error_model(est, quantities)
    lowest = {d.direction: min(d.factors) for d in est.directions}
    options = {d: tuple(f for f in REFINEMENTS if f >= lowest[d]) if d in lowest else (1.0,) for d in DIRECTIONS}
    limit = _memory_limit_bytes()
    out = []
    for fx in options["n_xi"]:
        for fe in options["n_eta"]:
            sc_mesh = refine(scene, n_xi=fx, n_eta=fe)
            for ft in options["dt"]:
                f = {"n_xi": fx, "n_eta": fe, "dt": ft}
                mem = run_bytes * fx * fe**2 * ft
                out.append((fx * fe * ft, model(f), f, sc_mesh, mem <= limit))
    out.sort(key=lambda c: c[0])
    return out


@dataclasses.dataclass(frozen=True)
class _Verified:
    scene: Scene
    estimate: DiscretisationError
    value_um: float
    predicted_um: float
    factors: dict
    rounds: int


def _factors_text(f: dict) -> str:
    return ", ".join(f"{d} {'×' if d != 'dt' else '/'}{v:g}" for d, v in f.items() if v != 1.0) or "the scene's own"


def verification_cost_s(est: DiscretisationError, cost_multiple: float) -> float:
    """The predicted wall time of running and verifying a grid ``cost_multiple`` times as costly
    as ``est``'s: its run and its estimate's ladder, which costs ``est.cost_runs`` runs of the grid
    it was taken on (compilation apart)."""
    return cost_multiple * est.run_s * (1.0 + est.cost_runs)


def _verified_grid(scene, accuracy_um, quantities, solver, t_from, rounds, progress, runs,
                   max_cost_s: float = math.inf, started: float | None = None) -> _Verified:
    """The grid loop of :func:`choose_grid` (module docstring) for one model; ``max_cost_s`` the
    budget counted from ``started`` (``time.perf_counter()``; default now)."""
    started = time.perf_counter() if started is None else started
    base, factors_total = scene, {d: 1.0 for d in DIRECTIONS}
    base_est = estimate_error(scene, solver, t_from=t_from, progress=progress, runs=runs)
    verified = []  # (value µm, grid's factors) of every grid verified
    grew = ""  # said in a refusal: the estimate grew on refinement
    for r in range(1, rounds + 1):
        pick, best = None, None  # the cheapest candidate predicted to meet it; the best reachable one
        for cost, err, f, sc_mesh, fits in _candidates(base, base_est, quantities, base_est.run_bytes):
            if not fits or (err > accuracy_um and best is not None and err >= best[1]):
                continue
            cand = refine(sc_mesh, dt=f["dt"])
            if not admissible(cand):
                continue
            if best is None or err < best[1]:
                best = (cost, err, f, cand)
            if err <= accuracy_um:
                pick = (cost, err, f, cand)
                break
        if pick is None:
            if best is None:
                raise AccuracyError(f"accuracy_um = {accuracy_um:g}: no admissible grid within half the machine's "
                                    "memory")
            # verified anyway where a fit on a grid nearer the target may bridge the gap (the prediction
            # within twice the accuracy, and better than the grid it comes from); else refused
            if r == rounds or best[1] > 2.0 * accuracy_um or best[1] >= 0.9 * asked_value(base_est, quantities):
                raise AccuracyError(
                    f"accuracy_um = {accuracy_um:g}: no grid within half the machine's memory reaches it: the error "
                    f"model of the last grid estimated (its own {asked_value(base_est, quantities):.3g} µm) predicts "
                    f"{best[1]:.3g} µm at best (refined {_factors_text(best[2])})"
                    + ("" if not verified else f"; the best grid verified reads {min(verified)[0]:.3g} µm") + grew)
            pick = best  # verified anyway, and the model fitted again on it (a prediction is not a verdict)
        cost, predicted, f, cand = pick
        predicted_s = verification_cost_s(base_est, cost)
        spent = time.perf_counter() - started
        if spent + predicted_s > max_cost_s:
            raise AccuracyError(
                f"accuracy_um = {accuracy_um:g}: the cheapest grid predicted to reach {predicted:.3g} µm (refined "
                f"{_factors_text(f)} against the grid estimated last) would take about {predicted_s:.3g} s to run "
                f"and verify, {spent:.3g} s spent already, over the budget of {max_cost_s:g} s (max_cost_s)" + grew)
        est = estimate_error(cand, solver, t_from=t_from, progress=progress, runs=runs)
        factors_total = {d: factors_total[d] * f[d] for d in DIRECTIONS}
        value = asked_value(est, quantities)
        verified.append((value, factors_total))
        if value <= accuracy_um:
            return _Verified(cand, est, value, predicted, factors_total, r)
        before = asked_value(base_est, quantities)
        if value >= before:  # the coarser grid's estimate was not in the asymptotic range
            grew = (f" (the estimate grew on refinement, {before:.3g} → {value:.3g} µm: the coarser grids' runs "
                    "agreed on a transient they all damp away; in a run from rest, the idle rollers' start-up "
                    "swing, which Backward Euler damps less at a smaller time step (docs/speed.md); judge the "
                    "error after the start-up, t_from (--from), or start running)")
        if progress:
            progress(f"the grid predicted at {predicted:.3g} µm reads {value:.3g} µm: the error model is fitted "
                     "again on it")
        if r == rounds:
            raise AccuracyError(
                f"accuracy_um = {accuracy_um:g}: the chosen grid's estimate is still {value:.3g} µm after "
                f"{rounds} rounds (each fitting the error model again on the grid before)" + grew)
        base, base_est = cand, est
    raise AssertionError("unreachable")  # pragma: no cover


def _judge(name, cheaper: TracerRun, reference: TracerRun, diff, value_um, accuracy_um, taken, beyond) -> ModelCheck:
    """A cheaper run's :class:`ModelCheck`: taken (``why`` = ``taken``) where the answer's
    ``value_um`` plus the measured difference ``diff`` meets the accuracy (else ``beyond``) and
    the cheaper run is faster than the reference."""
    if value_um + diff > accuracy_um:
        return ModelCheck(name, diff, cheaper.run_s, reference.run_s, False, beyond)
    if cheaper.run_s >= reference.run_s:
        return ModelCheck(name, diff, cheaper.run_s, reference.run_s, False,
                          f"not faster here ({cheaper.run_s:.3g} s against {reference.run_s:.3g} s)")
    return ModelCheck(name, diff, cheaper.run_s, reference.run_s, True, taken)


def _try_1d(scene, accuracy_um, quantities, solver, t_from, rounds, progress, runs_2d, runs_1d, max_cost_s=math.inf,
            started=None):
    """``(verified 1D grid or None, ModelCheck)``: the 1D counterpart where it is admissible,
    faster and within the accuracy with the measured model difference added (``runs_1d`` keeps
    its runs)."""
    s1, why = one_d_counterpart(scene)
    if s1 is None:
        return None, ModelCheck("1d", None, None, None, False, why)
    if not admissible(s1):
        return None, ModelCheck("1d", None, None, None, False, "the 1D counterpart's grid is not admissible")
    g = scene_grid(scene)
    if g not in runs_2d:
        runs_2d[g] = tracer_run(scene, solver)
    ref = runs_2d[g]
    own = runs_1d[scene_grid(s1)] = tracer_run(s1, solver)
    if own.u.shape != ref.u.shape:
        return None, ModelCheck("1d", None, own.run_s, ref.run_s, False, "the 1D counterpart records other tracers")
    diff = window_difference_um(own, ref, scene, quantities, t_from)
    check = _judge("1d", own, ref, diff, 0.0, accuracy_um, why,
                   f"the 1D and 2D models differ by {diff:.3g} µm, not within the accuracy")
    if not check.used:
        return None, check
    try:
        v = _verified_grid(s1, accuracy_um - diff, quantities, solver, t_from, rounds, progress, runs_1d, max_cost_s,
                           started)
    except AccuracyError:
        return None, dataclasses.replace(
            check, used=False, why=f"no 1D grid meets the accuracy less the model difference ({diff:.3g} µm) "
                                   "within the budget")
    return v, check


def _try_reuse(scene, value_um, accuracy_um, quantities, t_from, reference: TracerRun):
    """``(scene with the reuse solver or None, ModelCheck)``: the direct integrator's reuse solver
    (the first step's factors, refined) on the chosen grid against the scene's own solver, taken
    where its measured difference fits and it is faster."""
    if scene.solver.integrator != "direct" or scene.solver.linear_solver == "reuse":
        return None, ModelCheck("reuse", None, None, reference.run_s, False,
                                f"the scene runs {scene.solver.integrator}/{scene.solver.linear_solver}")
    sc = scene.replace(solver=dataclasses.replace(scene.solver, linear_solver="reuse"))
    r = tracer_run(sc)
    diff = window_difference_um(r, reference, scene, quantities, t_from)
    check = _judge("reuse", r, reference, diff, value_um, accuracy_um,
                   f"it reproduces the {scene.solver.linear_solver} solver to {diff:.3g} µm and is faster",
                   f"it differs by {diff:.3g} µm, beyond the accuracy")
    return ((sc, r) if check.used else None), check


def _try_float32(scene, value_um, accuracy_um, quantities, solver, t_from, reference: TracerRun) -> ModelCheck:
    """The float32 run of the chosen grid against its float64 run (the module docstring's rule)."""
    try:
        with precision_scope("float32"):
            r32 = tracer_run(scene, solver)
    except (NonFiniteStateError, FloatingPointError) as e:
        return ModelCheck("float32", None, None, reference.run_s, False, f"the float32 run failed: {e}")
    diff = window_difference_um(r32, reference, scene, quantities, t_from)
    return _judge("float32", r32, reference, diff, value_um, accuracy_um,
                  f"its rounding ({diff:.3g} µm, measured) leaves the answer within the accuracy",
                  f"its rounding ({diff:.3g} µm) on top of the estimate exceeds the accuracy")


def choose_grid(scene: Scene, accuracy_um: float, quantities=None, solver=None, *, t_from: float = 0.0,
                rounds: int = 3, progress=None, allow_1d: bool = False, allow_float32: bool = False,
                allow_reuse: bool = True, max_cost_s: float = DEFAULT_MAX_COST_S) -> GridChoice:
    """The cheapest run of ``scene`` whose estimated error is at most ``accuracy_um`` for the
    ``quantities`` (``longitudinal``/``lateral``; default both the scene has), verified by its
    own estimate (module docstring). ``AccuracyError`` (naming the best reachable error and its
    cost) when no grid within half the machine's memory reaches it. ``t_from``: the error is
    taken over the output times from then on (:func:`~jaxbelt.accuracy.estimate_error`).
    ``allow_1d``: run a symmetric 2D scene's 1D counterpart where the measured model difference
    allows; ``allow_float32``: run in float32 where its measured rounding allows (the caller
    builds and runs the chosen scene inside :func:`precision_scope`); ``allow_reuse``: try the
    reuse solver where the caller leaves the solver to the scene (``False`` for answers made of
    batched runs); ``max_cost_s``: the wall-time budget of the whole choice; each grid's run and
    verification is checked against it, with its predicted cost and the time spent, before it runs (``AccuracyError`` naming the predicted cost where
    the cheapest choice is over it)."""
    if not (isinstance(accuracy_um, (int, float)) and math.isfinite(accuracy_um) and accuracy_um > 0):
        raise ValueError(f"accuracy_um = {accuracy_um}: must be a positive number of µm")
    quantities = tuple(quantities or (QUANTITIES if scene.kind == "2d" else ("longitudinal",)))
    unknown = [q for q in quantities if q not in QUANTITIES]
    if unknown:
        raise ValueError(f"quantities {unknown}: unknown (one of {', '.join(QUANTITIES)})")
    started = time.perf_counter()
    automatic = [f"solver {scene.solver.integrator}/{scene.solver.linear_solver} (the scene's)"]
    checks, runs, runs_1d = [], {}, {}
    v, model_diff = None, 0.0
    if allow_1d and scene.kind == "2d":
        v1, check = _try_1d(scene, accuracy_um, quantities, solver, t_from, rounds, progress, runs, runs_1d,
                            max_cost_s, started)
        checks.append(check)
        if v1 is not None:
            v, model_diff = v1, check.difference_um
            automatic.append(f"model 1d: {check.why}; the models differ by {check.difference_um:.3g} µm (measured)")
        else:
            automatic.append(f"model 2d: {check.why}")
    if scene.kind == "1d":
        quantities = tuple(q for q in quantities if q == "longitudinal") or ("longitudinal",)
    if v is None:
        v = _verified_grid(scene, accuracy_um, quantities, solver, t_from, rounds, progress, runs, max_cost_s, started)
    value = v.value_um + model_diff
    chosen_scene, precision, cost_s = v.scene, "float64", v.estimate.run_s
    reference = None
    try_reuse = solver is None and allow_reuse
    if try_reuse or allow_float32:
        g = scene_grid(v.scene)
        reference = (runs if v.scene.kind == scene.kind else runs_1d).get(g)
        reference = reference if reference is not None else tracer_run(v.scene, solver)
    if solver is None and not allow_reuse:
        automatic[0] += ": the answer runs in batches, which share the exact solver's kept factors"
    if try_reuse:
        taken, check = _try_reuse(v.scene, value, accuracy_um, quantities, t_from, reference)
        checks.append(check)
        if taken is not None:
            (chosen_scene, reference), value, cost_s = taken, value + check.difference_um, check.run_s
            automatic[0] = f"solver direct/reuse: {check.why}"
        else:
            automatic[0] = f"solver {scene.solver.integrator}/{scene.solver.linear_solver} (the scene's): {check.why}"
    if allow_float32:
        check = _try_float32(chosen_scene, value, accuracy_um, quantities, solver, t_from, reference)
        checks.append(check)
        if check.used:
            precision, value, cost_s = "float32", value + check.difference_um, check.run_s
        automatic.append(f"precision {precision}: {check.why}")
    else:
        automatic.append("precision float64 (float32 is not considered for this answer)")
    return GridChoice(
        scene=chosen_scene, grid=v.estimate.grid, factors=v.factors,
        solver=f"{chosen_scene.solver.integrator}/{chosen_scene.solver.linear_solver}", precision=precision,
        estimate=v.estimate, estimate_um=value, predicted_um=v.predicted_um + model_diff, cost_s=cost_s,
        accuracy_um=accuracy_um, quantities=quantities, rounds=v.rounds, automatic=tuple(automatic),
        model=chosen_scene.kind, checks=tuple(checks))
