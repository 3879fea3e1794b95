"""Steady operation solved directly: the fixed point of the machine's one-period map.

A belt machine in steady operation repeats itself: after one controller sample period the state
on the fixed grid is what it was (the grid is fixed in space and the transport step keeps the
belt's moving material on it, §3.5). With ``Φ`` the map of one period — ``n_p`` Backward-Euler
steps, each with its transport step and (on a steered machine) the controller update, exactly the
steps :func:`jaxbelt.simulate` takes — steady operation is the fixed point

    x* = Φ(x*),

solved here by Newton's method on ``F(x) = Φ(x) − x`` with GMRES on the Jacobian-vector products
of ``Φ`` (:func:`jaxbelt.linalg.newton.newton_krylov`, :func:`jaxbelt.linalg.gmres.gmres`). Because ``Φ``
is the time stepper's own map, a long time-stepped run settles onto ``x*`` to the solver's
tolerance, not to a discretisation error. Derivatives come from the implicit function theorem
(``jax.lax.custom_root``): ``dx*/dθ = (I − ∂Φ/∂x)⁻¹ ∂Φ/∂θ``, one linear solve per tangent
(forward mode) or one transposed solve (reverse mode), never through the iterations; the solve
is jit- and vmap-able over misalignments and gains. Where the tangents along given directions
are wanted with the solve, :func:`steady_with_tangents` takes them in the same loop as Newton's
steps, on one linearisation of ``Φ`` (one compiled program for the solve with and without them).

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
damps them by far over a period) and close to the identity only in the slow ones: the element
masses carried round the loop (eigenvalues of ``∂Φ/∂x`` near the unit circle: a mass pattern
travels round the belt, damped only by the upwind diffusion), the loop's lateral modes and the
lightly damped low belt modes. GMRES's iterations go to those slow directions. The mass
transport is known in closed form (the transport step's upwind matrix, eq. 3.57), so it is
inverted exactly as a right preconditioner
(:class:`~jaxbelt.steady.preconditioner.MassTransportPreconditioner`); the belt's
own slow modes are left to GMRES. Newton takes three steps from the static equilibrium: the first
removes the start guess's large velocity residual, the response is nearly linear after it, and
each step's GMRES is asked for no more reduction than ends the iteration
(:func:`jaxbelt.linalg.newton.newton_krylov`). Measured on the design scene
(``benchmarks/steady_state.py``): 60–75
GMRES iterations per solve (one linearised period each), 100–130 without the preconditioner,
and 0.1–0.2 s per solve. No preconditioner from the step's factors: it would act on the fast
modes, which GMRES resolves in its first iterations anyway.
"""

from __future__ import annotations

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from ..control import ControllerState, samples_per_update, sensor_displacement
from ..integrators import AbstractIntegrator, make_solver
from ..model import BeltModel
from ..infra.programs import stored_jit
from ..linalg.newton import (DEFAULT_GMRES_CYCLES, DEFAULT_GMRES_RESTART, krylov_solve, newton_krylov,
                            newton_krylov_tangents)
from ..state import BeltState, initial_state
from ..run_checks import check_time_step
from ..timeloop import edge_margin, make_step, tracer_values
from .preconditioner import mass_transport_preconditioner, preconditioned

UNIT = 1e6  # m → µm, rad → µrad: the scaled unknowns' unit
DEFAULT_TOL_UM = 1e-6  # the residual RMS that ends Newton, µm: its solutions agree with a 1e-9 solve to ~1e-5 µm
UNBOUNDED = 1e30  # the lifted actuator range and rate limit of the steady map (rad, rad/s)
DEFAULT_MAX_NEWTON = 8
ADJOINT_KRYLOV_RTOL = 1e-8  # per tangent (implicit function theorem)


class SteadyState(eqx.Module):
    """A machine's steady operation (:func:`steady_state`; :func:`steady_walk`).

    **Fields:** ``state`` the steady :class:`~jaxbelt.BeltState` at the start of a period (step
    0); ``tracer_u``, ``tracer_v`` (n_tr,) the tracers' displacements there, m (``tracer_v``
    ``None`` in 1D); ``angle`` (n_c,) the actuators' steady angles, rad (``None`` without a loop);
    ``sensor_v`` (n_c,) the belt's lateral displacement at the sensors, m; ``edge_margin`` (p,) the
    smallest distance from a belt edge to its roller face's end, m (``None`` in 1D); ``walk_rate``
    () the uniform lateral walk, m/s (zero for :func:`steady_state`); ``residual`` () the last
    residual at the solution, µm (max norm of the scaled ``F``); ``newton_steps`` (); ``krylov_iterations`` ()
    GMRES iterations of all Newton steps (each one linearised period); ``converged`` ();
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
    krylov_iterations: jax.Array
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


def state_fields(state: BeltState):
    """The fields of a state that steady operation solves for (module docstring, *The unknowns*), as
    a tuple: what :func:`linear_start` takes derivatives of."""
    c = state.control
    ctrl = None if c is None else (c.integral, c.error, c.command, c.angle)
    return state.u, state.u_dot, state.chi, state.chi_dot, state.m_e, ctrl


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


def _tangent_solver(pre, tangent_rtol, restart, cycles):
    """The implicit function theorem's linear solve ``(∂F/∂y) dy = b`` (``tangent_solve(g, b)``, ``g``
    the linearised residual): GMRES (:func:`jaxbelt.linalg.newton.krylov_solve`) preconditioned by
    ``pre``, its transposed solve of reverse mode by the same GMRES on the transposed linearisation
    (:func:`jax.lax.custom_linear_solve`). A tangent GMRES could not find is NaN, never a silent number."""

    def tangent_solve(g, b):
        def gm(mv, r, transpose=False):
            x, missed = krylov_solve(mv, r, tangent_rtol, restart, cycles, preconditioned(pre, r, transpose))
            return jax.tree.map(lambda a: jnp.where(missed, jnp.nan, a), x)
        return lax.custom_linear_solve(g, b, solve=gm, transpose_solve=lambda mv, r: gm(mv, r, True))

    return tangent_solve


class _Solution(eqx.Module):
    value: object  # the root, scaled unknowns
    residual: jax.Array  # max |F| at the root, µm
    newton_steps: jax.Array
    krylov_iterations: jax.Array
    successful: jax.Array


def _solve(fn, y0, model, solver, template, dt, n, tol, max_steps, restart, gmres_steps, tangent_rtol,
           precondition: bool = True) -> _Solution:
    """Newton on ``fn(y, (model, run_data)) = 0`` from ``y0``
    (:func:`jaxbelt.linalg.newton.newton_krylov`), its derivatives by the implicit function theorem
    (:func:`jax.lax.custom_root`): a tangent ``dy`` solves ``(∂F/∂y) dy = −(∂F/∂θ) dθ`` by
    :func:`jaxbelt.linalg.newton.krylov_solve` on the linearised map, the transposed solve of
    reverse mode by the same GMRES on the transposed linearisation (:func:`jax.lax.custom_linear_solve`).
    No host callback anywhere in the program: a program holding one is never written to JAX's
    persistent compilation cache (``optimistix.ImplicitAdjoint`` checks its solve through one;
    measured: every process compiled the tangents again, 69 s on the default scene)."""
    run_data = lax.stop_gradient(solver.init(model, template, dt))
    f = lambda y: fn(y, (model, run_data))  # noqa: E731
    pre = mass_transport_preconditioner(model, dt, n) if precondition else None

    def newton_solve(f, guess):
        y, rms, residual, steps, its = newton_krylov(f, guess, tol, max_steps, restart, gmres_steps,
                                                     preconditioned(pre, guess))
        ok = rms <= tol
        # aux as floats: custom_root gives its aux float tangents, which integer outputs cannot take
        return y, (residual, steps.astype(residual.dtype), its.astype(residual.dtype), ok.astype(residual.dtype))

    tangent_solve = _tangent_solver(pre, tangent_rtol, restart, gmres_steps)

    value, (residual, steps, its, ok) = lax.custom_root(f, y0, newton_solve, tangent_solve, has_aux=True)
    return _Solution(value, lax.stop_gradient(residual), lax.stop_gradient(steps).astype(jnp.int32),
                     lax.stop_gradient(its).astype(jnp.int32), lax.stop_gradient(ok) > 0)


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
        residual=sol.residual, newton_steps=sol.newton_steps, krylov_iterations=sol.krylov_iterations,
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
def _steady(model, solver, dt, n, template, sc, tol, max_steps, restart, gmres_steps, tangent_rtol, precondition):
    q = quiet(model)
    fn = _residual(solver, dt, n, sc, template, walking=False)
    y0 = _pack(template, sc)
    sol = _solve(fn, y0, q, solver, template, dt, n, tol, max_steps, restart, gmres_steps, tangent_rtol, precondition)
    return _result(q, dt, n, sol.value, sc, template, jnp.zeros((), dt.dtype), sol, tol)


@stored_jit
def _walk(model, solver, dt, n, template, sc, tol, max_steps, restart, gmres_steps, tangent_rtol, precondition):
    q = quiet(model)
    fn = _residual(solver, dt, n, sc, template, walking=True)
    y0 = (_pack(template, sc), jnp.zeros((), dt.dtype))
    sol = _solve(fn, y0, q, solver, template, dt, n, tol, max_steps, restart, gmres_steps, tangent_rtol, precondition)
    return _result(q, dt, n, sol.value[0], sc, template, sol.value[1], sol, tol)


def steady_state(model: BeltModel, solver: AbstractIntegrator | None = None, *, dt, y0: BeltState | None = None,
                 period_steps: int | None = None,
                 tol: float = DEFAULT_TOL_UM, max_newton: int = DEFAULT_MAX_NEWTON,
                 restart: int = DEFAULT_GMRES_RESTART, krylov_cycles: int = DEFAULT_GMRES_CYCLES,
                 tangent_rtol: float = ADJOINT_KRYLOV_RTOL, precondition: bool = True) -> SteadyState:
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
    linear model that nonlinear solves verify needs far less: 1e-6 gives 1e-4); ``precondition``
    whether GMRES runs with
    :class:`~jaxbelt.steady.preconditioner.MassTransportPreconditioner` (same answer to the
    tolerances, fewer iterations).
    """
    if walks(model):
        raise ValueError("steady_state: this machine walks (lateral transport without a steering loop); "
                         "its steady operation is steady_walk's")
    solver, n, dt, template, sc = _setup(model, solver, dt, y0, period_steps)
    return _steady(model, solver, dt, n, template, sc, tol, max_newton, restart, krylov_cycles, tangent_rtol,
                   precondition)


def steady_walk(model: BeltModel, solver: AbstractIntegrator | None = None, *, dt, y0: BeltState | None = None,
                 period_steps: int | None = None,
                tol: float = DEFAULT_TOL_UM, max_newton: int = DEFAULT_MAX_NEWTON,
                restart: int = DEFAULT_GMRES_RESTART, krylov_cycles: int = DEFAULT_GMRES_CYCLES,
                 tangent_rtol: float = ADJOINT_KRYLOV_RTOL, precondition: bool = True) -> SteadyState:
    """The open-loop walking machine's steady walk: stationary up to a uniform lateral drift whose
    rate (``walk_rate``, m/s) is an unknown (module docstring). Arguments as :func:`steady_state`;
    a steering loop, if the model has one, is removed (the loop held open at zero angle)."""
    if model.kind != "2d":
        raise ValueError("steady_walk: a 1D belt has no lateral motion")
    model = model.replace(control=None)
    solver, n, dt, template, sc = _setup(model, solver, dt, y0, period_steps)
    return _walk(model, solver, dt, n, template, sc, tol, max_newton, restart, krylov_cycles, tangent_rtol,
                 precondition)


def steady_with_tangents(model: BeltModel, solver: AbstractIntegrator | None = None, *, dt, directions=None,
                         n_tangents=None, y0: BeltState | None = None, period_steps: int | None = None,
                         tol: float = DEFAULT_TOL_UM, max_newton: int = DEFAULT_MAX_NEWTON,
                         tangent_rtol: float = ADJOINT_KRYLOV_RTOL, restart: int = DEFAULT_GMRES_RESTART,
                         krylov_cycles: int = DEFAULT_GMRES_CYCLES, precondition: bool = True):
    """The steady operation of ``model`` (:func:`steady_state`'s, or :func:`steady_walk`'s where the
    machine walks) and its derivatives along the rows of ``directions`` (k, q) in ``chi_static``:
    ``(SteadyState, tangents)``, ``tangents`` the derivatives at ``t = 0`` of the steady state of
    ``model.replace(chi_static=chi_static + t @ directions)`` — its tracers' displacements
    ``(tracer_u, tracer_v)``, the actuators' angles, :func:`state_fields` and the walk rate, m/s —
    each with a trailing axis k.

    One loop (:func:`jaxbelt.linalg.newton.newton_krylov_tangents`): the Newton iteration, then per
    direction one tangent solve ``(∂F/∂x) dx = −(∂F/∂t) eᵢ`` at the solution (implicit function
    theorem; the same solve as :func:`steady_state`'s derivatives), every pass on one joint
    linearisation of the period map. Its compiled program holds the period map once as a primal and
    once linearised (a solve and a separate tangent program hold it six times between them;
    ``benchmarks/steady_state.py`` measures both compilations), and it is the one program of a
    model's shapes: ``n_tangents`` (traced,
    default k) takes the first so many directions, the others' tangents are NaN, and ``0`` makes it
    a plain solve (:func:`jaxbelt.steady.steady_states` on a CPU calls it so, with ``directions``
    its default, zeros (q, q)). ``y0`` the start (default the static equilibrium); other arguments
    as :func:`steady_state`. A tangent whose GMRES failed is NaN."""
    solver, n, dt, template, sc = _setup(model, solver, dt, y0, period_steps)
    q = model.chi_static.shape[0]
    directions = jnp.zeros((q, q), model.chi_static.dtype) if directions is None else jnp.asarray(directions)
    count = directions.shape[0] if n_tangents is None else n_tangents
    if not isinstance(count, jax.core.Tracer) and not 0 <= int(count) <= directions.shape[0]:
        raise ValueError(f"steady_with_tangents: n_tangents = {count}: must lie in 0..{directions.shape[0]} "
                         "(the rows of directions)")
    if directions.ndim != 2 or directions.shape[1] != q:
        raise ValueError(f"steady_with_tangents: directions of shape {directions.shape}: must be (k, {q}) "
                         "(one row per direction in chi_static)")
    # the tolerances and counts as arrays: a call with other values runs the same compiled program
    real = lambda a: jnp.asarray(a, dt.dtype)  # noqa: E731
    return _steady_with_tangents(model, solver, dt, n, template, sc, directions, jnp.asarray(count, jnp.int32),
                                 real(tol), jnp.asarray(max_newton, jnp.int32), real(tangent_rtol), restart,
                                 jnp.asarray(krylov_cycles, jnp.int32), precondition)


@stored_jit
def _steady_with_tangents(model, solver, dt, n, template, sc, directions, count, tol, max_newton, tangent_rtol,
                          restart, cycles, precondition):
    walking = walks(model)
    configure = lambda t: model.replace(chi_static=model.chi_static + t @ directions)  # noqa: E731
    start = _pack(template, sc)
    return _with_tangents(configure, jnp.zeros(directions.shape[0], directions.dtype), solver, n, dt, template,
                          sc, (start, jnp.zeros((), dt.dtype)) if walking else start, walking, None, tol,
                          max_newton, tangent_rtol, restart, cycles, precondition, count)


def steady_tangents(configure, theta, s: SteadyState, solver: AbstractIntegrator | None = None, *, dt,
                    outputs=None, tangent_rtol: float = ADJOINT_KRYLOV_RTOL, restart: int = DEFAULT_GMRES_RESTART,
                    krylov_cycles: int = DEFAULT_GMRES_CYCLES, precondition: bool = True):
    """The derivatives at ``theta`` (P,) of a known steady state ``s`` (:func:`steady_state` of
    ``configure(theta)``, or :func:`steady_walk`'s where that model walks) with respect to the
    parameters of ``configure(theta) -> BeltModel``, any parameterisation of the machine: the tangent
    solves of :func:`steady_with_tangents`, in the same loop, started at ``s`` (whose Newton
    iteration ends at once where ``s`` meets the default tolerance). ``outputs(model, state,
    walk_rate) -> pytree`` (default :func:`steady_with_tangents`'s outputs); each output's
    derivative gets a trailing axis P. Pure, jit-able."""
    model0 = configure(theta)
    solver, n, dt, template, sc = _setup(model0, solver, dt, s.state, s.period_steps)
    walking = walks(model0)
    y = _pack(s.state, sc)
    y = lax.stop_gradient((y, s.walk_rate * (UNIT * n * dt)) if walking else y)
    return _with_tangents(configure, theta, solver, n, dt, template, sc, y, walking, outputs, DEFAULT_TOL_UM,
                          DEFAULT_MAX_NEWTON, tangent_rtol, restart, krylov_cycles, precondition, None)[1]


def _with_tangents(configure, theta, solver, n, dt, template, sc, start, walking, outputs, tol, max_newton,
                   tangent_rtol, restart, cycles, precondition, count):
    outputs = _default_outputs if outputs is None else outputs
    fn = _residual(solver, dt, n, sc, template, walking=walking)
    q0 = quiet(configure(theta))
    run_data = lax.stop_gradient(solver.init(q0, template, dt))
    pre = mass_transport_preconditioner(q0, dt, n) if precondition else None

    def F(y, th):
        return fn(y, (quiet(configure(th)), run_data))

    y, rms, mx, steps, its, dys, _ = newton_krylov_tangents(F, start, theta, tol, max_newton, tangent_rtol,
                                                            restart, cycles, preconditioned(pre, start), count)

    def state_out(y, th):
        v, c = y if walking else (y, jnp.zeros((), dt.dtype))
        return outputs(configure(th), _unpack(v, template, sc), c / (UNIT * n * dt))

    columns = jax.vmap(lambda dy, e: jax.jvp(state_out, (y, theta), (dy, e))[1])(
        dys, jnp.eye(theta.size, dtype=theta.dtype))
    sol = _Solution(y, mx, steps, its, rms <= tol)
    v, c = y if walking else (y, jnp.zeros((), dt.dtype))
    return _result(q0, dt, n, v, sc, template, c, sol, tol), jax.tree.map(lambda a: jnp.moveaxis(a, 0, -1), columns)


def _default_outputs(model: BeltModel, state: BeltState, walk_rate):
    tu, tv = tracer_values(model, state.u)
    return tu, tv, None if model.control is None else state.control.angle, state_fields(state), walk_rate


def walks(model: BeltModel) -> bool:
    """Whether the machine walks: a 2D belt with lateral transport and no steering loop, whose
    steady operation is :func:`steady_walk`'s (stationary only up to a uniform lateral drift)."""
    return model.kind == "2d" and model.control is None and bool(model.lateral_transport)
