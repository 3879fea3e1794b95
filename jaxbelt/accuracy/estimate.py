"""How far a run's tracers are from the converged solution (mesh and time step → 0).

**The estimate** (:func:`estimate_error`). The error of a run is split into three directions of
the discretisation, each refined on its own with the other two held: the element length along
the belt (``n_xi``), the grid lines across it (``n_eta``, 2D only) and the time step (``dt``).
In each direction a ladder of three grids ``h₁ > h₂ > h₃`` (ratio 2, the scene's own grid one of
them) gives the observed order ``p`` from the ratio of the successive differences of the tracer
histories (rms over tracers and output times),

    ‖Q₁ − Q₂‖ / ‖Q₂ − Q₃‖ = (h₁ᵖ − h₂ᵖ) / (h₂ᵖ − h₃ᵖ),

and Richardson's extrapolation ``Q∞ = Q₃ + (Q₃ − Q₂) / ((h₂/h₃)ᵖ − 1)`` the converged history
in that direction; the scene grid's error in it is ``E_d = Q_scene − Q∞`` at every tracer and
output time. The estimate is ``F_s max_{t, tracer} |Σ_d E_d|`` with Roache's safety factor
``F_s = 1.25`` of the three-grid Grid Convergence Index, for the longitudinal (``u``) and the
lateral (``v``) tracer displacement. The directions' errors are summed with their signs: along
and across the belt they often cancel in part (on the three-roller machine the lateral error of
the grid refined in every direction is under half of either direction's alone), and a sum of
magnitudes would overstate the error accordingly. ``dominant`` names the direction with the
largest ``max |E_d|``; each direction reports its observed order.

Which ladder a direction takes: one level coarser and one finer than the scene where the coarser
grid is admissible (CFL ``V Δt < ℓ_min``, at least 5 elements per arc, a controller's sampling
time a whole number of steps, a whole number of steps in the run), else two finer. A finer mesh
along the belt needs a smaller step (CFL): that ladder runs at the largest ``Δt / 2ᵏ`` its finest
mesh admits, and its error is that of the mesh at that step (the directions are assumed
separable, as the sum assumes). The order comes from the output times all three grids have (the multiples of their largest step); the error is
taken at every output time of the scene, from the two finest grids, whose steps divide the
scene's — the largest error often sits at the first step, where the drive starts impulsively.

The observed order is kept in ``[0.5, 4]``: outside it the ladder is not in its asymptotic range
(the clamp is reported). A direction whose differences are at round-off contributes nothing.
"""

from __future__ import annotations

import dataclasses
import math
import time

import jax
import numpy as np

from ..build import build_model
from ..infra.results import to_json
from ..mesh import build_mesh
from ..scene import Scene, SceneError
from ..state import initial_state
from ..run_checks import check_finite
from ..timeloop import RunOptions, SaveAt, simulate

DIRECTIONS = ("n_xi", "n_eta", "dt")
SAFETY_FACTOR = 1.25  # Roache's F_s for a three-grid study
ORDER_RANGE = (0.5, 4.0)
# refinement factors of the ladders, in order of preference (1 = the scene's grid)
LADDERS = ((0.5, 1.0, 2.0), (1.0, 2.0, 4.0))


@dataclasses.dataclass(frozen=True)
class Grid:
    """A run's discretisation: ``n_xi`` elements along the belt (all segments), ``n_eta`` grid
    lines across (1 in 1D), ``dt`` the time step (s)."""

    n_xi: int
    n_eta: int
    dt: float


def scene_grid(scene: Scene) -> Grid:
    """The grid a scene runs on."""
    return Grid(int(len(build_mesh(scene).ell)), int(scene.mesh.n_eta), float(scene.time.dt))


def refine(scene: Scene, *, n_xi: float = 1.0, n_eta: float = 1.0, dt: float = 1.0) -> Scene:
    """The scene on a grid refined by the given factors (``< 1``: coarser): element counts along
    the belt times ``n_xi`` (explicit per-segment counts scaled each), element rows across times
    ``n_eta`` (2D), the time step divided by ``dt``; the horizon, outputs and everything else
    kept. Not checked: :func:`jaxbelt.build_mesh` says whether the result is admissible."""
    m = scene.mesh
    if n_xi != 1.0:
        if m.roller_elements is not None:
            m = dataclasses.replace(m, roller_elements=tuple(max(1, round(c * n_xi)) for c in m.roller_elements),
                                    free_elements=tuple(max(1, round(c * n_xi)) for c in m.free_elements))
        elif m.element_length is not None:
            m = dataclasses.replace(m, element_length=m.element_length / n_xi)
        else:
            total = m.n_xi if m.n_xi is not None else len(build_mesh(scene).ell)
            m = dataclasses.replace(m, n_xi=max(1, round(total * n_xi)))
    if n_eta != 1.0 and scene.kind == "2d":
        m = dataclasses.replace(m, n_eta=max(1, round((m.n_eta - 1) * n_eta)) + 1)
    time_spec = scene.time if dt == 1.0 else dataclasses.replace(scene.time, dt=scene.time.dt / dt)
    return scene.replace(mesh=m, time=time_spec)


def admissible(scene: Scene) -> bool:
    """Whether the scene's grid can run: the mesh checks (CFL, elements per arc, the belt path),
    a whole number of steps, and every steering loop's sampling time a whole number of steps."""
    steps = scene.time.t_end / scene.time.dt
    if abs(steps - round(steps)) > 1e-6 * max(1.0, steps) or round(steps) < 1:
        return False
    for c in scene.control:
        if c.sample is not None:
            k = c.sample / scene.time.dt
            if abs(k - round(k)) > 1e-6 * max(1.0, k) or round(k) < 1:
                return False
    try:
        build_mesh(scene)
    except SceneError:
        return False
    return True


@dataclasses.dataclass(frozen=True)
class DirectionError:
    """One direction's part of :class:`DiscretisationError`.

    **Fields:** ``direction`` (``n_xi``, ``n_eta`` or ``dt``); ``factors`` the ladder's refinement
    factors (1: the scene's grid); ``dt_s`` the time step the ladder ran at; ``order`` the
    observed order (``None``: the differences are at round-off); ``order_clamped`` whether it was
    outside ``ORDER_RANGE``; ``longitudinal_um``/``lateral_um`` the largest ``|E_d|`` over tracers
    and output times (µm; lateral ``None`` in 1D)."""

    direction: str
    factors: tuple[float, ...]
    dt_s: float
    order: float | None
    order_clamped: bool
    longitudinal_um: float
    lateral_um: float | None


@dataclasses.dataclass(frozen=True)
class DiscretisationError:
    """:func:`estimate_error`'s result.

    **Fields:** ``longitudinal_um``, ``lateral_um`` the estimated largest tracer error over the
    output times against the converged solution (µm; lateral ``None`` in 1D); ``dominant`` the
    direction contributing most; ``directions`` each direction's :class:`DirectionError`;
    ``grid`` the scene's :class:`Grid`; ``safety_factor``; ``run_s`` the wall time of the scene's
    own run (compilation apart); ``estimate_s`` the wall time of the whole estimate (every run,
    compilation included); ``runs_s`` the summed run times of the ladders (compilation apart);
    ``cost_runs`` ``runs_s / run_s``; ``run_bytes`` XLA's memory estimate of the scene's run;
    ``t_from_s`` the start of the output times the error is taken over."""

    longitudinal_um: float
    lateral_um: float | None
    dominant: str
    directions: tuple[DirectionError, ...]
    grid: Grid
    safety_factor: float
    run_s: float
    estimate_s: float
    runs_s: float
    cost_runs: float
    run_bytes: float
    t_from_s: float = 0.0

    def direction(self, name: str) -> DirectionError:
        return next(d for d in self.directions if d.direction == name)

    def to_dict(self) -> dict:
        """The JSON form (``discretisation_error_um`` of ``jaxbelt simulate --error-estimate``)."""
        return to_json(dict(
            longitudinal=self.longitudinal_um, lateral=self.lateral_um, dominant=self.dominant,
            orders={d.direction: d.order for d in self.directions},
            directions={d.direction: dict(longitudinal_um=d.longitudinal_um, lateral_um=d.lateral_um, order=d.order,
                                          order_clamped=d.order_clamped, factors=list(d.factors), dt_s=d.dt_s)
                        for d in self.directions},
            grid=dataclasses.asdict(self.grid), t_from_s=self.t_from_s, safety_factor=self.safety_factor,
            run_s=self.run_s,
            estimate_s=self.estimate_s, cost_runs=self.cost_runs))


@dataclasses.dataclass(frozen=True)
class TracerRun:
    """:func:`tracer_run`'s result: the tracer histories of one run at every step, and its cost."""

    t: np.ndarray  # (k,) output times, s
    u: np.ndarray  # (k, n_tr) longitudinal tracer displacement, m
    v: np.ndarray | None  # (k, n_tr) lateral, or None
    run_s: float
    run_bytes: float  # XLA's memory estimate of the compiled run (arguments, outputs, temporaries)


def tracer_run(scene: Scene, solver=None) -> TracerRun:
    """The scene's tracer histories at every step (its own solver unless ``solver``), the run
    compiled ahead and timed apart; a non-finite state raises
    :class:`~jaxbelt.NonFiniteStateError`."""
    model = build_model(scene)
    opts = RunOptions.from_scene(scene)
    solver = opts.solver if solver is None else solver
    y0 = initial_state(model, start=scene.time.start)
    go = jax.jit(lambda m, dt, y0: simulate(m, solver, n_steps=opts.n_steps, dt=dt, y0=y0, saveat=SaveAt(),
                                            check=False)[1])
    dt = jax.numpy.asarray(opts.dt, model.ell.dtype)
    compiled = go.lower(model, dt, y0).compile()
    mem = compiled.memory_analysis()
    run_bytes = (8.0 * model.n_unknowns * 64 * opts.n_steps if mem is None else
                 float(mem.argument_size_in_bytes + mem.output_size_in_bytes + mem.temp_size_in_bytes))
    t0 = time.perf_counter()
    traj = jax.block_until_ready(compiled(model, dt, y0))
    run_s = time.perf_counter() - t0
    check_finite(traj, opts.dt)
    return TracerRun(np.asarray(traj.t), np.asarray(traj.tracer_u),
                     None if traj.tracer_v is None else np.asarray(traj.tracer_v), run_s, run_bytes)


def at_times(run: TracerRun, dt_run: float, dt_common: float, k: int, t_from: float = 0.0):
    """``(u, v)`` rows of a run with step ``dt_run`` at the times ``dt_common, 2 dt_common, …,
    k dt_common`` (``dt_common`` a whole multiple of ``dt_run``) from ``t_from`` on; ``v`` is
    ``None`` in 1D."""
    stride = int(round(dt_common / dt_run))
    first = max(1, int(math.ceil(t_from / dt_common - 1e-9)))
    rows = np.arange(min(first, k), k + 1) * stride - 1
    return run.u[rows], None if run.v is None else run.v[rows]


def observed_order(h, q):
    """The observed order ``p`` of three levels ``h[0] > h[1] > h[2]`` with solutions ``q``
    (arrays): solves ``‖q₀ − q₁‖/‖q₁ − q₂‖ = (h₀ᵖ − h₁ᵖ)/(h₁ᵖ − h₂ᵖ)`` (rms norms) by bisection.
    ``(p, clamped)``; ``(None, False)`` where both differences are at round-off."""
    d01 = float(np.sqrt(np.mean((q[0] - q[1]) ** 2)))
    d12 = float(np.sqrt(np.mean((q[1] - q[2]) ** 2)))
    scale = max(float(np.max(np.abs(q[2]))), 1e-12)
    if max(d01, d12) <= 1e-11 * scale:
        return None, False
    lo, hi = ORDER_RANGE
    if d12 <= 1e-14 * scale:
        return hi, True

    def g(p):
        return (h[0] ** p - h[1] ** p) / (h[1] ** p - h[2] ** p)

    ratio = d01 / d12
    if ratio <= g(lo):
        return lo, True
    if ratio >= g(hi):
        return hi, True
    a, b = lo, hi
    for _ in range(60):
        mid = 0.5 * (a + b)
        a, b = (mid, b) if g(mid) < ratio else (a, mid)
    return 0.5 * (a + b), False


def richardson_limit(h, q, p):
    """Richardson's extrapolation of the two finest levels ``q[1], q[2]`` (at ``h[1] > h[2]``)
    with order ``p``: the converged solution's estimate."""
    if p is None:
        return q[2]
    r = h[1] / h[2]
    return q[2] + (q[2] - q[1]) / (r**p - 1.0)


def _ladder(scene: Scene, direction: str):
    """``(factors, scenes)``: the first admissible ladder of :data:`LADDERS` for the
    direction; along the belt, at the smallest refinement of the step its finest mesh admits."""
    for factors in LADDERS:
        if direction == "dt":
            scenes = [refine(scene, dt=f) for f in factors]
            if all(admissible(s) for s in scenes):
                return factors, scenes
            continue
        for k in range(4):
            scenes = [refine(scene, dt=2.0**k, **{direction: f}) for f in factors]
            if direction == "n_eta" and len({s.mesh.n_eta for s in scenes}) < 3:
                break
            if all(admissible(s) for s in scenes):
                return factors, scenes
            if not admissible(scenes[0]):  # the coarse level itself is out (elements per arc): next ladder
                break
    raise SceneError(f"no admissible grid ladder in {direction} for scene {scene.name!r}")


def _h(scene: Scene, direction: str) -> float:
    g = scene_grid(scene)
    return {"n_xi": 1.0 / g.n_xi, "n_eta": 1.0 / max(g.n_eta - 1, 1), "dt": g.dt}[direction]


def estimate_error(scene: Scene, solver=None, *, t_from: float = 0.0, progress=None,
                   runs: dict | None = None) -> DiscretisationError:
    """The discretisation error of ``scene``'s run (its own solver unless ``solver``): the
    estimated largest tracer error over the output times from ``t_from`` on (s; default all)
    against the converged solution, per quantity, with the dominant direction and each
    direction's observed order (module docstring). A design metric read over a window asks for
    the error there: the drive's start-up, whose error converges slowly, lies before it.
    ``progress``: a callable taking a line of text, told of each run. ``runs``: a dict of
    :class:`TracerRun` by :class:`Grid` that the estimate reads and fills (one per scene and
    solver: several estimates on related grids share their runs through it)."""
    t_start = time.perf_counter()
    directions = ("n_xi", "dt") if scene.kind == "1d" else DIRECTIONS
    cache: dict = {} if runs is None else runs

    def run(sc: Scene) -> TracerRun:
        g = scene_grid(sc)  # the grid names the run: a ladder's level may be another ladder's
        if g not in cache:
            if progress:
                progress(f"run n_xi={g.n_xi} n_eta={g.n_eta} dt={g.dt:g} s")
            cache[g] = tracer_run(sc, solver)
        return cache[g]

    own = run(scene)
    ladders = {d: _ladder(scene, d) for d in directions}
    k_user = int(round(scene.time.t_end / scene.time.dt))
    parts, errs_u, errs_v = [], [], []
    for d in directions:
        factors, scenes = ladders[d]
        runs = [run(sc) for sc in scenes]
        hs = [_h(sc, d) for sc in scenes]
        # the order from the three levels at the times they all have; the error at every output
        # time of the scene from the two finest levels (both have them: their steps divide the scene's)
        dt_common = max(sc.time.dt for sc in scenes)
        k = int(math.floor(scene.time.t_end / dt_common + 1e-9))
        common = [at_times(r, sc.time.dt, dt_common, k, t_from) for r, sc in zip(runs, scenes)]
        user = [at_times(r, sc.time.dt, scene.time.dt, k_user, t_from) for r, sc in zip(runs, scenes)]
        at = factors.index(1.0)
        errs = []
        for c in (0, 1):
            if common[0][c] is None:
                errs.append((None, None, False))
                continue
            p, clamped = observed_order(hs, [q[c] for q in common])
            limit = richardson_limit(hs, [None, user[1][c], user[2][c]], p)
            errs.append((user[at][c] - limit, p, clamped))
        (eu, pu, cu), (ev, pv, cv) = errs
        errs_u.append(eu)
        errs_v.append(ev)
        # the order reported: that of the quantity with the larger error in this direction
        use_v = ev is not None and np.max(np.abs(ev)) > np.max(np.abs(eu))
        parts.append(DirectionError(
            direction=d, factors=tuple(factors), dt_s=float(scenes[at].time.dt),
            order=pv if use_v else pu, order_clamped=bool(cv if use_v else cu),
            longitudinal_um=float(np.max(np.abs(eu)) * 1e6),
            lateral_um=None if ev is None else float(np.max(np.abs(ev)) * 1e6)))
    long_um = SAFETY_FACTOR * float(np.max(np.abs(sum(errs_u)))) * 1e6
    lat_um = None if errs_v[0] is None else SAFETY_FACTOR * float(np.max(np.abs(sum(errs_v)))) * 1e6
    dominant = max(parts, key=lambda p: max(p.longitudinal_um, p.lateral_um or 0.0)).direction
    used = {scene_grid(sc) for d in directions for sc in ladders[d][1]} - {scene_grid(scene)}
    runs_s = sum(cache[g].run_s for g in used)
    return DiscretisationError(
        longitudinal_um=long_um, lateral_um=lat_um, dominant=dominant, directions=tuple(parts),
        grid=scene_grid(scene), safety_factor=SAFETY_FACTOR, run_s=own.run_s,
        estimate_s=time.perf_counter() - t_start, runs_s=runs_s, cost_runs=runs_s / max(own.run_s, 1e-12),
        run_bytes=own.run_bytes, t_from_s=float(t_from))
