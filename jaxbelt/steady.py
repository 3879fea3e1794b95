"""Steady operation solved directly: the fixed point of the machine's one-period map.

A belt machine in steady operation repeats itself: after one controller sample period the state
on the fixed grid is what it was (the grid is fixed in space and the transport step keeps the
belt's moving material on it, §3.5). With ``Φ`` the map of one period — ``n_p`` Backward-Euler
steps, each with its transport step and (on a steered machine) the controller update, exactly the
steps :func:`jaxbelt.simulate` takes — steady operation is the fixed point

    x* = Φ(x*),

solved here by Newton's method on ``F(x) = Φ(x) − x`` with GMRES on the Jacobian-vector products
of ``Φ`` (:mod:`optimistix` ``root_find`` with ``Newton``, restarted GMRES as a :mod:`lineax` solver,
:class:`RelativeGMRES`). Because ``Φ``
is the time stepper's own map, a long time-stepped run settles onto ``x*`` to the solver's
tolerance, not to a discretisation error. Derivatives come from the implicit function theorem
(``jax.lax.custom_root``): ``dx*/dθ = (I − ∂Φ/∂x)⁻¹ ∂Φ/∂θ``, one linear solve per tangent
(forward mode) or one transposed solve (reverse mode), never through the iterations; the solve
is jit- and vmap-able over misalignments and gains.

**What is solved, and decisions where the specification is silent:**

- *The period* ``n_p``: the least common multiple of the loops' sample counts ``sample / Δt``
  (one step without a loop). The controller samples at the period's first step.
- *The unknowns*: belt displacement and velocity, roller DOFs and rates, element masses, and the
  controllers' integral, last error, held command and actuator angle. The step counter and the
  belt's travel are not unknowns: they only time the sensor noise and the edge profile, which
  steady operation leaves out (:func:`quiet`: both act alike on an aligned and a misaligned
  machine, and cancel in a deviation; the actuator jitter they cause is measured once by a
  time-stepped run, :func:`actuator_jitter`).
- *The actuator range and rate limit* are lifted in the solve: steady operation has a constant
  angle, so the rate limit never acts, and the angle the loop needs is found even where it lies
  beyond the range — which is then reported against the range (no steady state), not clipped.
- *Mass*: the transport step conserves the belt's mass, so ``Φ`` leaves the total mass where it
  finds it and ``F`` is singular along the family of steady states of other total masses. The
  mass rows of the residual get ``(Σ m − M₀) / n`` added (``M₀`` the model's belt mass), which
  picks the member of the family with the belt's own mass and makes the Jacobian regular; at the
  solution the added term is zero, so the fixed point is unchanged.
- *Units*: the unknowns are scaled to µm (lengths), µm over one period (velocities), µrad
  (angles) and ppm of the element's rest mass, so one absolute tolerance means the same in every
  block; ``tol`` is that tolerance on the residual, in µm (its RMS ends the Newton iteration; the
  solve counts as converged when that holds, or when the residual's largest entry is within it).
- *The walking machine* (lateral transport, no loop): its belt walks, so it repeats itself only
  up to a uniform lateral shift. :func:`steady_walk` solves ``Φ(x) = x + c e_v`` with the phase
  condition that the belt's mean lateral displacement is that of the start state; the walk per
  period ``c`` is an unknown, the walk rate ``c / T``.

**Iterations.** ``Φ`` is strongly contracting in the belt's fast elastic modes (Backward Euler
damps them by far over a period) and close to the identity only in the slow ones: the loop's
lateral modes and the lightly damped low belt modes. GMRES's iterations go to those few slow
directions, so an unpreconditioned GMRES needs some tens of Jacobian-vector products per
Newton step, each one period of linearised steps with the step's factors kept. Newton takes
3–5 steps: the first removes the start guess's large velocity residual, the response is nearly
linear after it (measured: ``benchmarks/steady_state.py``). No preconditioner is used: one from
the step's factors would act on the fast modes, which GMRES resolves in its first iterations
anyway; the slow, transported directions are where its iterations go.
"""

from __future__ import annotations

import dataclasses
import math

import equinox as eqx
import jax
import jax.flatten_util
import jax.scipy.sparse.linalg
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx
from jax import lax

from .control import ControllerState, samples_per_update, sensor_displacement
from .integrators import AbstractIntegrator, make_solver
from .model import BeltModel
from .infra.programs import stored_jit
from .state import BeltState, initial_state
from .timeloop import SaveAt, belt_speed, check_time_step, edge_margin, make_step, simulate, tracer_values

UNIT = 1e6  # m → µm, rad → µrad: the scaled unknowns' unit
DEFAULT_TOL_UM = 1e-5
UNBOUNDED = 1e30  # the lifted actuator range and rate limit of the steady map (rad, rad/s)
JITTER_TURNS = 2.0  # belt turns of the time-stepped run that measures the actuator jitter
DEFAULT_MAX_NEWTON = 8
DEFAULT_GMRES_RESTART = 200
DEFAULT_GMRES_CYCLES = 6
STAGE_RTOL = 1e-6  # the most one GMRES solve is asked to reduce its residual (RelativeGMRES)
NEWTON_KRYLOV_RTOL = 1e-3  # GMRES's residual reduction per Newton step
ADJOINT_KRYLOV_RTOL = 1e-8  # per tangent (implicit function theorem)


class SteadyState(eqx.Module):
    """A machine's steady operation (:func:`steady_state`; :func:`steady_walk`).

    **Fields:** ``state`` the steady :class:`~jaxbelt.BeltState` at the start of a period (step
    0); ``tracer_u``, ``tracer_v`` (n_tr,) the tracers' displacements there, m (``tracer_v``
    ``None`` in 1D); ``angle`` (n_c,) the actuators' steady angles, rad (``None`` without a loop);
    ``sensor_v`` (n_c,) the belt's lateral displacement at the sensors, m; ``edge_margin`` (p,) the
    smallest distance from a belt edge to its roller face's end, m (``None`` in 1D); ``walk_rate``
    () the uniform lateral walk, m/s (zero for :func:`steady_state`); ``residual`` () the last
    Newton residual, µm (max norm of the scaled ``F``); ``newton_steps`` (); ``converged`` ();
    ``period_steps`` (static) steps per period.
    """

    state: BeltState
    tracer_u: jax.Array
    tracer_v: jax.Array | None
    angle: jax.Array | None
    sensor_v: jax.Array | None
    edge_margin: jax.Array | None
    walk_rate: jax.Array
    residual: jax.Array
    newton_steps: jax.Array
    converged: jax.Array
    period_steps: int = eqx.field(static=True)


class NoSteadyStateError(ValueError):
    """The machine has no steady operation (one line: what was found)."""


def quiet(model: BeltModel) -> BeltModel:
    """The model without sensor noise and edge profile, its actuators' range and rate limit lifted
    (module docstring): the machine whose fixed point is steady operation."""
    loops = model.control
    if loops is None:
        return model
    # "no limit" as a huge finite bound, not inf: the implicit derivative differentiates the map with
    # respect to every model field, and a zero tangent times an infinite bound is NaN
    inf = jnp.full_like(loops.limit, UNBOUNDED)
    loops = eqx.tree_at(lambda c: (c.noise, c.profile_amplitude, c.limit, c.rate_limit), loops,
                        (jnp.zeros_like(loops.noise), jnp.zeros_like(loops.profile_amplitude), inf, inf))
    return model.replace(control=loops)


def period_steps(model: BeltModel, dt) -> int:
    """Steps per period: the least common multiple of the loops' ``sample / Δt`` (1 without a
    loop); ``dt`` and the sample periods must be concrete (under a transformation, pass the period
    of the concrete model to :func:`steady_state`)."""
    if model.control is None:
        return 1
    if isinstance(dt, jax.core.Tracer) or isinstance(model.control.sample, jax.core.Tracer):
        raise ValueError("steady_state: the period needs concrete dt and sample periods; pass period_steps "
                         "(jaxbelt.steady.period_steps of the concrete model) under jit/vmap/grad")
    n = np.asarray(samples_per_update(model.control, float(dt)))
    return int(math.lcm(*(int(k) for k in n)))


class _Scales(eqx.Module):
    """Per-block scales of the unknowns (module docstring, *Units*)."""

    period: jax.Array
    m_e0: jax.Array


def _pack(state: BeltState, sc: _Scales):
    """The scaled unknowns of ``state`` (:func:`state_fields`, in the units of the module docstring)."""
    u, ud, chi, chid, m, ctrl = state_fields(state)
    ctrl = None if ctrl is None else tuple(a * UNIT for a in ctrl)
    return (u * UNIT, ud * UNIT * sc.period, chi * UNIT, chid * UNIT * sc.period, (m / sc.m_e0 - 1.0) * UNIT, ctrl)


def _unpack(y, template: BeltState, sc: _Scales) -> BeltState:
    u, ud, chi, chid, m, ctrl = y
    control = None
    if ctrl is not None:
        control = ControllerState(integral=ctrl[0] / UNIT, error=ctrl[1] / UNIT, command=ctrl[2] / UNIT,
                                  angle=ctrl[3] / UNIT, travel=jnp.zeros((), u.dtype))
    return BeltState(u=u / UNIT, u_dot=ud / (UNIT * sc.period), chi=chi / UNIT, chi_dot=chid / (UNIT * sc.period),
                     m_e=(1.0 + m / UNIT) * sc.m_e0, step=jnp.zeros((), jnp.int32), control=control)


@eqx.filter_jit
def _period_map(model: BeltModel, solver: AbstractIntegrator, dt, n: int, run_data, state: BeltState) -> BeltState:
    """``Φ(state)``: ``n`` steps of :func:`jaxbelt.timeloop.make_step` from a state at step 0. Its own
    ``jit``: the Newton solve, its linearisation, transposition and batching all call the one period
    map, which is then traced once per solve instead of once per use (the step is a large program,
    and its Python tracing was most of a solve's start-up)."""
    step = make_step(model, solver, dt, run_data)
    return lax.scan(lambda s, _: (step(s)[0], None), state, None, length=n)[0]


def _lateral_direction(y):
    """``e_v`` in the scaled unknowns: a uniform unit lateral shift of every belt node."""
    e = jax.tree.map(jnp.zeros_like, y)
    u = e[0].at[:, 1::2].set(1.0)
    return (u,) + tuple(e[1:])


def _residual(solver, dt, n, sc, template, walking: bool):
    """``F(y, (model, run_data))`` of the root find (and of the augmented walk system)."""

    def phi_scaled(y, args):
        m, run_data = args
        s = _unpack(y, template, sc)
        return _pack(_period_map(m, solver, dt, n, run_data, s), sc)

    def mass_row(y, f):
        total = jnp.sum((1.0 + y[4] / UNIT) * sc.m_e0) - jnp.sum(sc.m_e0)
        return f[:4] + (f[4] + total / jnp.sum(sc.m_e0) * UNIT,) + f[5:]

    if not walking:
        def fn(y, args):
            f = jax.tree.map(lambda a, b: a - b, phi_scaled(y, args), y)
            return mass_row(y, f)
        return fn

    def fn_walk(yc, args):
        y, c = yc
        e = _lateral_direction(y)
        f = jax.tree.map(lambda a, b, d: a - b - c * d, phi_scaled(y, args), y, e)
        f = mass_row(y, f)
        phase = jnp.mean(y[0][:, 1::2]) - jnp.mean(template.u[:, 1::2]) * UNIT
        return f, phase

    return fn_walk


def staged_gmres(matvec, b, rtol: float, restart: int = DEFAULT_GMRES_RESTART, cycles: int = DEFAULT_GMRES_CYCLES):
    """Restarted GMRES on ``matvec(x) = b`` (pytrees) stopped at ``‖r‖₂ ≤ rtol ‖b‖₂``: ``(x, missed)``,
    ``missed`` true where the solve ended a thousand times above the tolerance. A tight tolerance is
    met in stages of at most :data:`STAGE_RTOL` each (iterative refinement: each stage solves for the
    residual the ones before left): a single GMRES asked for a residual near round-off breaks down in
    its least-squares update and returns NaN."""
    b_flat, unravel = jax.flatten_util.ravel_pytree(b)
    mv = lambda x: jax.flatten_util.ravel_pytree(matvec(unravel(x)))[0]  # noqa: E731
    stages = max(1, math.ceil(math.log(rtol) / math.log(STAGE_RTOL) - 1e-9))
    stage_rtol = rtol ** (1.0 / stages)
    x, r = jnp.zeros_like(b_flat), b_flat
    for _ in range(stages):
        zero = jnp.linalg.norm(r) == 0  # (e.g. a tangent the map does not feel): 0, not GMRES's 0/0
        dx, _ = jax.scipy.sparse.linalg.gmres(mv, jnp.where(zero, 1.0, r), tol=stage_rtol, atol=0.0,
                                              restart=restart, maxiter=cycles, solve_method="incremental")
        x = x + jnp.where(zero | ~jnp.all(jnp.isfinite(dx)), 0.0, dx)
        r = b_flat - mv(x)
    missed = jnp.linalg.norm(r) > 1e3 * rtol * jnp.linalg.norm(b_flat)
    return unravel(x), missed


class RelativeGMRES(lx.AbstractLinearSolver):
    """Restarted GMRES (:func:`jax.scipy.sparse.linalg.gmres`) as a :mod:`lineax` solver, stopped when
    ``‖r‖₂ ≤ rtol ‖b‖₂``: the usual inexact-Newton criterion, one scale for the whole vector.
    ``lineax.GMRES`` scales its tolerance entry by entry (``atol + rtol |b_i|``), which asks every
    entry for its own relative accuracy, also the many nearly-zero entries of a Newton residual:
    measured on the steered machine, it did not stop. ``restart`` Krylov vectors per cycle, at
    most ``cycles`` cycles; a solve that ends a thousand times above the tolerance is reported (``max_steps_reached``)."""

    rtol: float
    restart: int = DEFAULT_GMRES_RESTART
    cycles: int = DEFAULT_GMRES_CYCLES

    def init(self, operator, options):
        return operator

    def compute(self, state, vector, options):
        x, missed = staged_gmres(state.mv, vector, self.rtol, self.restart, self.cycles)
        result = lx.RESULTS.where(missed, lx.RESULTS.max_steps_reached, lx.RESULTS.successful)
        return x, result, {}

    def transpose(self, state, options):
        return state.transpose(), options

    def conj(self, state, options):
        return state.conj(), options

    def assume_full_rank(self):
        return True


class _Solution(eqx.Module):
    value: object  # the root, scaled unknowns
    residual: jax.Array  # max |F| where the last Newton step started, µm
    newton_steps: jax.Array
    successful: jax.Array


def _solve(fn, y0, model, solver, template, dt, tol, max_steps, restart, gmres_steps, tangent_rtol) -> _Solution:
    """Newton on ``fn(y, (model, run_data)) = 0`` from ``y0`` (optimistix), its derivatives by the
    implicit function theorem (:func:`jax.lax.custom_root`): a tangent ``dy`` solves
    ``(∂F/∂y) dy = −(∂F/∂θ) dθ`` by :func:`staged_gmres` on the linearised map, the transposed solve of
    reverse mode by the same GMRES on the transposed linearisation (:func:`jax.lax.custom_linear_solve`).
    ``optimistix.ImplicitAdjoint`` does the same through ``lineax.linear_solve``, which checks its
    result with a host callback; a program holding a host callback is never written to JAX's
    persistent compilation cache, so every process compiled the tangents again (measured: 69 s on
    the default scene)."""
    gmres = RelativeGMRES(NEWTON_KRYLOV_RTOL, restart, gmres_steps)
    # ended by the residual: RMS(F) < tol (the step only has to be smaller than the state itself). A
    # criterion on the step's size alone keeps Newton going once F is at round-off, where GMRES
    # cannot reduce it further.
    newton = optx.Newton(rtol=1.0, atol=tol, linear_solver=gmres, norm=optx.rms_norm)
    run_data = lax.stop_gradient(solver.init(model, template, dt))
    f = lambda y: fn(y, (model, run_data))  # noqa: E731

    def newton_solve(f, guess):
        sol = optx.root_find(lambda y, _: f(y), newton, guess, max_steps=max_steps, throw=False)
        residual = jax.tree.reduce(jnp.maximum, jax.tree.map(lambda a: jnp.max(jnp.abs(a)), sol.state.f))
        ok = sol.result == optx.RESULTS.successful
        # aux as floats: custom_root gives its aux float tangents, which integer outputs cannot take
        return sol.value, (residual, jnp.asarray(sol.stats["num_steps"], residual.dtype), ok.astype(residual.dtype))

    def tangent_solve(g, b):
        def gm(mv, r):  # a tangent GMRES could not find is NaN, never a silent number
            x, missed = staged_gmres(mv, r, tangent_rtol, restart, gmres_steps)
            return jax.tree.map(lambda a: jnp.where(missed, jnp.nan, a), x)
        return lax.custom_linear_solve(g, b, solve=gm, transpose_solve=gm)

    value, (residual, steps, ok) = lax.custom_root(f, y0, newton_solve, tangent_solve, has_aux=True)
    return _Solution(value, lax.stop_gradient(residual), lax.stop_gradient(steps).astype(jnp.int32),
                     lax.stop_gradient(ok) > 0)


def _result(model, dt, n, y, sc, template, walk_per_period, sol: _Solution, tol):
    state = _unpack(y, template, sc)
    tu, tv = tracer_values(model, state.u)
    loops = model.control
    return SteadyState(
        state=state, tracer_u=tu, tracer_v=tv,
        angle=None if loops is None else state.control.angle,
        sensor_v=None if loops is None else sensor_displacement(loops, state.u),
        edge_margin=edge_margin(model, state.u, state.chi) if model.kind == "2d" else None,
        walk_rate=walk_per_period / (UNIT * n * dt),
        residual=sol.residual, newton_steps=sol.newton_steps,
        converged=sol.successful | (sol.residual <= tol), period_steps=n)


def _setup(model, solver, dt, y0, n=None):
    solver = make_solver() if solver is None else solver
    check_time_step(model, dt)
    n = period_steps(model, dt) if n is None else int(n)
    dt = jnp.asarray(dt, model.ell.dtype)
    template = initial_state(model) if y0 is None else y0
    template = dataclasses.replace(template, step=jnp.zeros((), jnp.int32))
    sc = _Scales(period=n * dt, m_e0=lax.stop_gradient(model.m_e0))
    return solver, n, dt, template, sc


@stored_jit
def _steady(model, solver, dt, n, template, sc, tol, max_steps, restart, gmres_steps, tangent_rtol):
    q = quiet(model)
    fn = _residual(solver, dt, n, sc, template, walking=False)
    y0 = _pack(template, sc)
    sol = _solve(fn, y0, q, solver, template, dt, tol, max_steps, restart, gmres_steps, tangent_rtol)
    return _result(q, dt, n, sol.value, sc, template, jnp.zeros((), dt.dtype), sol, tol)


@stored_jit
def _walk(model, solver, dt, n, template, sc, tol, max_steps, restart, gmres_steps, tangent_rtol):
    q = quiet(model)
    fn = _residual(solver, dt, n, sc, template, walking=True)
    y0 = (_pack(template, sc), jnp.zeros((), dt.dtype))
    sol = _solve(fn, y0, q, solver, template, dt, tol, max_steps, restart, gmres_steps, tangent_rtol)
    return _result(q, dt, n, sol.value[0], sc, template, sol.value[1], sol, tol)


def steady_state(model: BeltModel, solver: AbstractIntegrator | None = None, *, dt, y0: BeltState | None = None,
                 period_steps: int | None = None,
                 tol: float = DEFAULT_TOL_UM, max_newton: int = DEFAULT_MAX_NEWTON,
                 restart: int = DEFAULT_GMRES_RESTART, krylov_cycles: int = DEFAULT_GMRES_CYCLES,
                 tangent_rtol: float = ADJOINT_KRYLOV_RTOL) -> SteadyState:
    """Steady operation of a machine that is stationary on its grid: a steered machine, or one
    without lateral transport (module docstring). jit-, vmap- and differentiable (implicit
    function theorem) in the model's array fields.

    **Arguments:** ``solver`` the integrator of the map (default :func:`jaxbelt.make_solver`'s);
    ``dt`` the time step, s (concrete: it fixes the period); ``y0`` the start of the iteration
    (default the static equilibrium); ``period_steps`` steps per period (default
    :func:`period_steps`; give it under ``jit``/``vmap``/``grad``); ``tol`` the residual tolerance, µm; ``max_newton`` Newton
    steps; ``restart`` and ``krylov_cycles`` GMRES's Krylov vectors per cycle and cycles per solve;
    ``tangent_rtol`` GMRES's relative residual in each derivative's solve (forward tangent or
    transposed solve; the default's derivatives equal central differences to 1e-5 and better; a
    linear model that nonlinear solves verify needs far less: 1e-6 gives 1e-4).
    """
    if model.kind == "2d" and model.control is None and _walks(model):
        raise ValueError("steady_state: this machine walks (lateral transport without a steering loop); "
                         "its steady operation is steady_walk's")
    solver, n, dt, template, sc = _setup(model, solver, dt, y0, period_steps)
    return _steady(model, solver, dt, n, template, sc, tol, max_newton, restart, krylov_cycles, tangent_rtol)


def steady_walk(model: BeltModel, solver: AbstractIntegrator | None = None, *, dt, y0: BeltState | None = None,
                 period_steps: int | None = None,
                tol: float = DEFAULT_TOL_UM, max_newton: int = DEFAULT_MAX_NEWTON,
                restart: int = DEFAULT_GMRES_RESTART, krylov_cycles: int = DEFAULT_GMRES_CYCLES,
                 tangent_rtol: float = ADJOINT_KRYLOV_RTOL) -> SteadyState:
    """The open-loop walking machine's steady walk: stationary up to a uniform lateral drift whose
    rate (``walk_rate``, m/s) is an unknown (module docstring). Arguments as :func:`steady_state`;
    a steering loop, if the model has one, is removed (the loop held open at zero angle)."""
    if model.kind != "2d":
        raise ValueError("steady_walk: a 1D belt has no lateral motion")
    model = model.replace(control=None)
    solver, n, dt, template, sc = _setup(model, solver, dt, y0, period_steps)
    return _walk(model, solver, dt, n, template, sc, tol, max_newton, restart, krylov_cycles, tangent_rtol)


def map_configurations(fn, xs):
    """``fn`` over the leading axis of ``xs`` for functions that solve for a steady state: on a CPU
    one configuration after another (:func:`jax.lax.map`), elsewhere side by side (``vmap``).

    A batched Newton–GMRES runs its members' loops in lockstep: every GMRES iteration and Newton
    step is taken by the whole batch until its slowest member is done, and the Krylov basis's
    update at a batched iteration index is a scatter into the whole basis instead of an in-place
    column write. Measured on the design scene (``benchmarks/tolerance_latency.py``, a tolerance
    box's verification batch of eight solves at the aligned configuration, warm): 172 s as one
    ``vmap``, 1.5 s in sequence; on a CPU the cores a batch could fill are already busy with each
    solve's own linear algebra."""
    if jax.default_backend() == "cpu":
        return lax.map(fn, xs)
    return jax.vmap(fn)(xs)


def forward_jacobian(fn, theta, has_aux: bool = False):
    """``jax.jacfwd(fn, has_aux=has_aux)(theta)`` for functions that solve for a steady state: the
    primal solve once (:func:`jax.linearize`), then one tangent solve per component through
    :func:`map_configurations` (``jacfwd`` batches the tangents' GMRES loops in lockstep; measured on
    the design scene's fifteen tangents, warm: 4.9 s batched, 3.6 s in sequence). Each output gets
    a trailing axis of ``theta``'s length."""
    out = jax.linearize(fn, theta, has_aux=has_aux)
    lin = out[1]
    columns = map_configurations(lin, jnp.eye(theta.size, dtype=theta.dtype))
    J = jax.tree.map(lambda a: jnp.moveaxis(a, 0, -1), columns)
    return (J, out[2]) if has_aux else J


def _walks(model: BeltModel) -> bool:
    return bool(model.lateral_transport)


def state_fields(state: BeltState):
    """The fields of a state that steady operation solves for (module docstring, *The unknowns*), as
    a tuple: what :func:`linear_start` takes derivatives of."""
    c = state.control
    ctrl = None if c is None else (c.integral, c.error, c.command, c.angle)
    return state.u, state.u_dot, state.chi, state.chi_dot, state.m_e, ctrl


def linear_start(state: BeltState, tangents, theta) -> BeltState:
    """``x* + (dx*/dθ) θ``: a steady state moved along its derivatives (``tangents``: the
    :func:`state_fields` of ``dx*/dθ``, each with a trailing axis P; ``theta`` (P,)) — the start of
    a nearby steady solve, whose Newton iteration then only removes the nonlinear remainder."""
    u, ud, chi, chid, m, ctrl = jax.tree.map(lambda a, d: a + d @ theta, state_fields(state), tangents)
    control = state.control
    if ctrl is not None:
        control = dataclasses.replace(control, integral=ctrl[0], error=ctrl[1], command=ctrl[2], angle=ctrl[3])
    return dataclasses.replace(state, u=u, u_dot=ud, chi=chi, chi_dot=chid, m_e=m, control=control)


def check_steady(s, model: BeltModel, what: str = "the aligned machine"):
    """:class:`NoSteadyStateError` unless ``s`` (concrete) is a steady operation the
    machine can hold: converged, its actuators within their range, the belt on its rollers."""
    if not bool(s.converged) or not np.all(np.isfinite(np.asarray(s.tracer_u))):
        raise NoSteadyStateError(f"no steady operation of {what}: the fixed-point iteration did not converge "
                                 f"(residual {float(s.residual):.3g} µm after {int(s.newton_steps)} Newton steps)")
    if s.angle is not None:
        need, limit = np.abs(np.asarray(s.angle)), np.asarray(model.control.limit)
        for label, a, lim in zip(model.control.labels, need, limit):
            if a > lim:
                raise NoSteadyStateError(f"no steady operation of {what}: the loop on {label} needs {a * 1e3:.4g} mrad "
                                         f"to hold the belt, beyond its ±{lim * 1e3:.4g} mrad range")
    if s.edge_margin is not None and np.min(np.asarray(s.edge_margin)) < 0:
        raise NoSteadyStateError(f"no steady operation of {what}: the belt edge runs off a roller "
                                 f"({-np.min(np.asarray(s.edge_margin)) * 1e3:.3g} mm beyond its face)")


def actuator_jitter(model: BeltModel, integrator, dt, s: SteadyState, turns: float = JITTER_TURNS):
    """The aligned machine's actuator jitter around its steady angle, mrad (n_c,): the largest
    ``|angle − steady angle|`` of a time-stepped run of ``model`` (sensor noise and edge profile
    on) from its steady state ``s`` over ``turns`` belt turns. A loop whose steady state is not
    stable shows here: the deviation growing from the first turn to the last is named
    (:class:`NoSteadyStateError`)."""
    loops = model.control
    n = max(2, int(np.ceil(turns * float(loops.loop_length) / belt_speed(model) / float(dt))))
    y0 = dataclasses.replace(s.state, control=dataclasses.replace(s.state.control, travel=jnp.zeros((), dt.dtype)))
    _, tr = simulate(model, integrator, n_steps=n, dt=dt, y0=y0, saveat=SaveAt(), check=False)
    dev = np.abs(np.asarray(tr.control_u) - np.asarray(s.angle)[None])
    if not np.all(np.isfinite(dev)):
        raise NoSteadyStateError("no steady operation: the aligned machine's run from its steady state diverged "
                                 "(an unstable loop)")
    half = n // 2
    first, last = dev[:half].max(axis=0), dev[half:].max(axis=0)
    if np.any((last > 4 * first) & (last > 0.05 * np.asarray(loops.limit))):
        raise NoSteadyStateError(f"no steady operation: the steady state is unstable (actuator deviation grows from "
                                 f"{first.max() * 1e3:.3g} to {last.max() * 1e3:.3g} mrad over {turns:g} belt turns: "
                                 "a growing loop mode; lower the gains)")
    return jnp.asarray(dev.max(axis=0) * 1e3, dt.dtype)
