"""The time loop: solve → transport → outputs, as one jit-compiled ``lax.scan``; :func:`simulate`.

:func:`simulate` is the one way to run a model, in the shape of ``diffrax.diffeqsolve``: the
model is the physics, the call says how to integrate it (``solver``, ``dt``, ``n_steps``), what
to record (:class:`SaveAt`) and how reverse mode keeps memory (:class:`Checkpointed`). ``dt``,
material data and misalignments are traced values: another time step or another misalignment
runs the same compiled program. Only the step count and the structure of the solver and of the
records are static (a scan's length and its carry's shapes must be).

The run is pure: ``jax.grad`` differentiates through it (e.g. a tracer metric w.r.t.
``model.chi_static``) and ``jax.vmap`` batches it over models that differ in array fields. The
step's linear solve carries its own adjoint, which reuses the step's factors
(:mod:`jaxbelt.integrators.linear`), and the scan is checkpointed in chunks of ``~√n`` steps,
so memory grows as ``√n``, not ``n``, for one extra forward pass. The step is traced and compiled
once per run, whatever its length and record interval (:func:`jaxbelt.loop_plan.loop_plan`).
"""

from __future__ import annotations

import dataclasses
import functools
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .assembly import (free_belt_matvec, free_belt_stencil, generalised_belt_force, nodal_masses, roller_R,
                       static_surface_offset, stencil_matvec)
from .control import controller_update, measure, sensor_displacement
from .integrators import AbstractIntegrator, make_solver
from .linalg import join
from .loop_plan import checkpointed, loop_plan, scan_or_inline
from .model import BeltModel
from .run_checks import check_finite, check_start_masses, check_time_step, nonfinite_code
from .infra.programs import stored_jit
from .scene import Scene
from .state import BeltState, initial_state
from .transport import transport_step_with_weights


class SaveAt(eqx.Module):
    """What a run records (all static: they shape the compiled program).

    **Fields:** ``every``: keep every ``every``-th step (the records are the steps
    ``every, 2 every, …``); ``fields``: also the full displacement field ``u`` (k, n_xi, b);
    ``solved``: also the flat states before and after each step's transport
    (``x_solved``/``v_solved``, ``x_grid``/``v_grid``, (k, N)): the snapshots of model order
    reduction, returned by :func:`make_step` only.
    """

    every: int = eqx.field(static=True, default=1)
    fields: bool = eqx.field(static=True, default=False)
    solved: bool = eqx.field(static=True, default=False)

    def __check_init__(self):
        if int(self.every) < 1:
            raise ValueError(f"SaveAt(every={self.every}): must be at least 1")


class Checkpointed(eqx.Module):
    """Reverse mode through the run in checkpointed chunks (the forward result is the same).

    ``steps``: steps per chunk; ``None`` takes ``⌈√n⌉`` (:func:`jaxbelt.loop_plan.default_checkpoint_chunk`, moved to
    a divisor of the record count where there is one), so memory grows as ``√n`` for one extra
    forward pass; ``0``: no checkpointing (memory grows as ``n``)."""

    steps: int | None = eqx.field(static=True, default=None)


class Trajectory(eqx.Module):
    """Recorded outputs, one row per kept step. Units: s, m, rad, kg.

    ``t`` (k,); ``tracer_u`` (k, n_tr) longitudinal tracer displacement after transport;
    ``tracer_v`` (k, n_tr) lateral (2D; ``None`` in 1D);
    ``tracer_u_solved`` (k, n_tr) the same before transport (the solve's result);
    ``roller_state`` (k, p, d) roller DOFs as solved (``α_z`` = rotation during the step);
    ``roller_velocity`` (k, p, d); ``roller_reaction`` (k, p, d) support force (N) / torque (N·m)
    at prescribed roller DOFs, residual (≈ 0) at dynamic ones; ``belt_mass`` (k,); ``transport_weights`` (k, 2) min/max
    interpolation weight of the transport step (outside [0, 1) = extrapolation);
    ``edge_margin`` (k, p) 2D: the smallest distance (m) from a belt edge to the end of each
    roller's face over the belt nodes on that roller, negative once the belt runs off it
    (:func:`edge_margin`; ``None`` in 1D);
    ``nonfinite`` (k,) int8 NaN/inf guard: 0 while the state is finite, else the first part of
    it that is not (:data:`NONFINITE_CAUSES`: 1 belt displacement, 2 belt velocity, 3 roller
    state) — evaluated inside the scan, read once at the end (:func:`~jaxbelt.run_checks.check_finite`), no host sync
    per step;
    ``u`` (k, n_xi, b) or ``None``;
    ``control_u`` (k, n_c) the steering actuators' angles during each step, rad (added to the
    actuated rotations' static values; ``None`` without ``[[control]]``);
    ``sensor_v`` (k, n_c) the belt's lateral displacement at the sensors after each step, m
    (without the edge profile and the noise the sensors add; ``None`` without ``[[control]]``).
    """

    t: jax.Array
    tracer_u: jax.Array
    tracer_v: jax.Array | None
    tracer_u_solved: jax.Array
    roller_state: jax.Array
    roller_velocity: jax.Array
    roller_reaction: jax.Array
    belt_mass: jax.Array
    transport_weights: jax.Array
    edge_margin: jax.Array | None
    nonfinite: jax.Array
    u: jax.Array | None
    control_u: jax.Array | None = None
    sensor_v: jax.Array | None = None


def tracer_values(model: BeltModel, u):
    """``(u, v)`` at the tracers (n_tr,) each, from the element shape functions (linear in 1D,
    bilinear in 2D); ``v`` is ``None`` in 1D."""
    c, c1, xi = model.tracer_col, (model.tracer_col + 1) % model.n_xi, model.tracer_xi
    if model.kind == "1d":
        return (1.0 - xi) * u[c, 0] + xi * u[c1, 0], None
    r, e = model.tracer_row, model.tracer_eta

    def at(F):
        return ((1 - xi) * (1 - e) * F[c, r] + (1 - xi) * e * F[c, r + 1]
                + xi * (1 - e) * F[c1, r] + xi * e * F[c1, r + 1])

    return at(u[:, 0::2]), at(u[:, 1::2])


def edge_margin(model: BeltModel, u, chi):
    """Per roller (p,): ``min over its belt nodes of (W_j/2 − |z_edge + v_edge − d_z,j|)`` for both
    belt edges, in m; ``W_j`` the roller's face width, ``d_z,j`` its axial translation. Negative:
    the belt edge has left the roller's face (model specification §1 requires belt ≤ roller width at rest;
    lateral motion can still carry it off). ``+inf`` for a roller without belt nodes."""
    p, d = model.n_rollers, len(model.dofs)
    dz = chi.reshape(p, d)[:, model.dofs.index("dz")]
    v = u[:, 1::2]
    z_edges = jnp.stack([model.z0[0] + v[:, 0], model.z0[-1] + v[:, -1]], axis=1)  # (n, 2)
    j = jnp.maximum(model.node_roller, 0)
    margin = model.roller_half_width[j, None] - jnp.abs(z_edges - dz[j, None])
    margin = jnp.where((model.node_roller >= 0)[:, None], margin, jnp.inf).min(axis=1)
    # per roller a masked minimum ((p, n), fused) rather than segment_min's scatter, slow on a CPU
    return jnp.where(model.node_roller[None, :] == jnp.arange(p)[:, None], margin[None, :], jnp.inf).min(axis=1)


def make_step(model: BeltModel, solver: AbstractIntegrator, dt, run_data=None, saveat: SaveAt = SaveAt()):
    """``step(state) -> (state, record)``: one solve + transport with its outputs.

    **Arguments:** ``dt`` the time step, s; ``run_data`` what ``solver.init`` returned for this
    run (computed here from ``model`` and its initial state when ``None``, a convenience for single
    steps); ``saveat`` which records (:class:`SaveAt`; with ``solved`` the record also holds the
    flat states before and after transport, the snapshots of model order reduction).
    """
    p, d = model.n_rollers, len(model.dofs)
    if run_data is None:
        run_data = solver.init(model, initial_state(model), dt)
    stencil = free_belt_stencil(model)  # once per run, outside the scan
    offset = static_surface_offset(model)
    on = model.contact_columns  # R_r vanishes off the rollers: the loads need those columns only

    def roller_loads(state, solved):
        """``M_r χ̈ + Σ R_rᵀ f_k - Q_ext`` per roller DOF (§4 post-processing): at a prescribed DOF
        the force/torque its support must supply (what holds a misaligned roller, what the drive
        delivers); at a dynamic DOF the residual of its equation (≈ 0). The nodal forces ``f_k``
        are evaluated on the roller columns only (``model.contact_columns``), where ``R_r`` is
        non-zero."""
        a_u = (solved.u_dot - state.u_dot) / dt
        a_chi = (solved.chi_dot - state.chi_dot) / dt
        m = nodal_masses(model, state.m_e)
        if on is None or stencil is None:
            Kf_u = free_belt_matvec(model, solved.u) if stencil is None else stencil_matvec(stencil, solved.u)
            f = m * a_u + Kf_u + model.f0
            return model.M_roller * a_chi + generalised_belt_force(roller_R(model, state.u), f) - model.Q_ext
        idx = jnp.asarray(on, int)
        f = m[idx] * a_u[idx] + stencil_matvec(stencil, solved.u, on) + model.f0[idx]
        return model.M_roller * a_chi + generalised_belt_force(roller_R(model, state.u, on_rollers=True), f) \
            - model.Q_ext

    loops = model.control

    def steer(state: BeltState):
        """The steering loops' update before a step (:mod:`jaxbelt.control`): the model the step
        runs with (actuated rotations at static value + angle), the controller state, the angles."""
        if loops is None:
            return model, None, None
        reading = measure(loops, state.u, state.control.travel, state.step)
        ctrl, angle = controller_update(loops, state.control, reading, state.step, dt)
        dofs = jnp.asarray(loops.actuator_dof)
        return eqx.tree_at(lambda m: m.chi_static, model, model.chi_static.at[dofs].add(angle)), ctrl, angle

    def step(state: BeltState):
        step_model, ctrl, angle = steer(state)
        solved = solver.step(step_model, state, dt, run_data)
        u, ud, chi, m_e, weights = transport_step_with_weights(model, solved.u, solved.u_dot, solved.chi, state.m_e,
                                                               static_offset=offset, rule=solver.transport)
        if ctrl is not None:  # the material's travel: the transport step's shift (mean longitudinal motion)
            ctrl = eqx.tree_at(lambda c: c.travel, ctrl, ctrl.travel + jnp.mean(solved.u[:, 0::2]))
        new = BeltState(u=u, u_dot=ud, chi=chi, chi_dot=solved.chi_dot, m_e=m_e, step=state.step + 1, control=ctrl)
        tu, tv = tracer_values(model, u)
        rec = dict(
            t=(state.step + 1) * dt,
            tracer_u=tu,
            tracer_v=tv,
            tracer_u_solved=tracer_values(model, solved.u)[0],
            roller_state=solved.chi.reshape(p, d),
            roller_velocity=solved.chi_dot.reshape(p, d),
            roller_reaction=roller_loads(state, solved).reshape(p, d),
            belt_mass=jnp.sum(m_e),
            transport_weights=weights,
            edge_margin=edge_margin(model, u, new.chi) if model.kind == "2d" else None,
            nonfinite=nonfinite_code(u, ud, new.chi, new.chi_dot),
            control_u=angle,
            sensor_v=None if loops is None else sensor_displacement(loops, u),
        )
        if saveat.fields:
            rec["u"] = u
        if saveat.solved:
            rec["x_solved"] = join(solved.u, solved.chi)
            rec["v_solved"] = join(solved.u_dot, solved.chi_dot)
            rec["x_grid"] = join(new.u, new.chi)
            rec["v_grid"] = join(new.u_dot, new.chi_dot)
        return new, rec

    return step


def run(model: BeltModel, solver: AbstractIntegrator, state: BeltState, dt, n_steps: int,
        saveat: SaveAt = SaveAt(), checkpoint: int | None = None, run_data=None):
    """``n_steps`` steps from ``state``; records every ``saveat.every``-th (traceable; no checks).

    The loop is nested scans (:func:`jaxbelt.loop_plan.loop_plan`): chunks of about ``checkpoint`` steps (default
    ``⌈√n⌉``, :func:`jaxbelt.loop_plan.default_checkpoint_chunk`; ``0``: none) under ``jax.checkpoint``, so reverse
    mode through a long run stays in bounded memory (the forward result is the same), each chunk a
    scan over record intervals, each interval a scan over its steps. The step is traced and
    compiled once whatever ``n_steps`` and ``saveat.every`` are; a run whose length is no whole
    number of chunks ends on slots that skip the step. ``run_data``: ``solver.init``'s, default
    computed from ``state``.

    **Returns:** ``(final_state, Trajectory)``.
    """
    if run_data is None:
        run_data = solver.init(model, state, dt)
    step = make_step(model, solver, dt, run_data, SaveAt(saveat.every, saveat.fields))
    plan = loop_plan(n_steps, saveat.every, checkpoint)
    if plan.active is None and plan.n_sub * plan.sub_steps == 1:  # a record every step, none padded
        def record(s, _):
            return step(s)
    else:  # the record of an interval is the last one its steps make: carried, from zeros of its shapes
        rec0 = jax.tree.map(lambda a: jnp.zeros(a.shape, a.dtype), jax.eval_shape(step, state)[1])

        def slot(carry, on):
            if on is None:
                return step(carry[0]), None
            return lax.cond(on, lambda c: step(c[0]), lambda c: c, carry), None

        def sub_chunk(carry, on):
            return scan_or_inline(slot, carry, on, plan.sub_steps)[0], None

        def record(s, on):
            body = checkpointed(sub_chunk, plan.n_sub > 1)
            return scan_or_inline(body, (s, rec0), on, plan.n_sub)[0]

    active = None if plan.active is None else jnp.asarray(plan.active)

    def chunk(s, on):
        return scan_or_inline(record, s, on, plan.records_per_chunk)

    state, rec = scan_or_inline(checkpointed(chunk, plan.n_chunks > 1), state, active, plan.n_chunks)
    rec = jax.tree.map(lambda a: a.reshape(-1, *a.shape[2:])[:plan.n_out], rec)
    return state, Trajectory(u=rec.pop("u", None), **rec)


@stored_jit
def _simulate(model, solver, y0, dt, n_steps, saveat, adjoint, run_data):
    state = initial_state(model) if y0 is None else y0
    return run(model, solver, state, dt, n_steps, saveat, adjoint.steps, run_data)


@stored_jit
def _init_run(model, solver, y0, dt):
    state = initial_state(model) if y0 is None else y0
    return state, solver.init(model, state, dt)


def simulate(model: BeltModel, solver: AbstractIntegrator | None = None, *, n_steps: int, dt,
             saveat: SaveAt = SaveAt(), adjoint: Checkpointed = Checkpointed(), y0: BeltState | None = None,
             check: bool = True, progress: bool = False):
    """Simulate a model: ``n_steps`` steps of size ``dt`` from ``y0`` (jit-compiled; differentiable;
    vmap-able over the model's array fields, ``dt`` and ``y0``).

    **Arguments:**
    - ``model``: from :func:`jaxbelt.build_model`.
    - ``solver``: an integrator (:mod:`jaxbelt.integrators`), default
      ``DirectBackwardEuler(KeptInterior())`` with the shift transport.
    - ``n_steps``: number of steps (static: a new count is a new compile).
    - ``dt``: time step, s (traced: a new value is not). Checked against the transport step's CFL
      condition when concrete (:func:`~jaxbelt.run_checks.check_time_step`).
    - ``saveat``: what to record (:class:`SaveAt`).
    - ``adjoint``: checkpointing of reverse mode (:class:`Checkpointed`).
    - ``y0``: start state; default :func:`jaxbelt.initial_state` (static equilibrium). The
      default solver keeps its factors at the model's element masses (``m_e0``), which the shift
      transport never changes; a ``y0`` whose masses differ is refused (:func:`~jaxbelt.run_checks.check_start_masses`):
      it needs a solver that factors every step (``DirectBackwardEuler(Structured())``).
    - ``check``: raise :class:`~jaxbelt.run_checks.NonFiniteStateError` (step, time, cause) if the state became NaN/inf
      — a flag computed inside the scan and read once here; skipped under ``jit``/``grad``/``vmap``,
      where ``Trajectory.nonfinite`` carries it to the caller.
    - ``progress``: run in compiled chunks of ~200 steps with a progress bar (the result is the
      same; for long runs at the command line).

    :class:`RunOptions` holds a scene's own choices of all but ``y0``:
    ``simulate(model, **RunOptions.from_scene(scene))``.

    **Returns:** ``(final_state, Trajectory)``.
    """
    solver = make_solver() if solver is None else solver
    n_steps = int(n_steps)
    if n_steps < 0:
        raise ValueError(f"n_steps = {n_steps}: must be at least 0")
    check_time_step(model, dt)
    check_start_masses(model, solver, y0)
    dt = jnp.asarray(dt, dtype=model.ell.dtype)
    if progress:
        chunked = simulate_in_chunks(model, solver, n_steps=n_steps, dt=dt, saveat=saveat, adjoint=adjoint, y0=y0)
        out = chunked.state, chunked.trajectory
    else:
        out = _simulate(model, solver, y0, dt, n_steps, saveat, adjoint, None)
    if check:
        check_finite(out[1], dt)
    return out


def compile_simulate(model: BeltModel, solver: AbstractIntegrator | None = None, *, n_steps: int, dt,
                     saveat: SaveAt = SaveAt(), adjoint: Checkpointed = Checkpointed(), y0: BeltState | None = None):
    """Compile, without running it, the program :func:`simulate` runs for these arguments; a later
    :func:`simulate` call with the same shapes and settings finds it. Nothing executes, so a
    background thread can compile while the caller runs other programs (two XLA:CPU executions at
    once can wedge its thread pool; compiling beside one cannot)."""
    compile_simulation(model, solver, n_steps=n_steps, dt=dt, saveat=saveat, adjoint=adjoint, y0=y0)


@dataclasses.dataclass(frozen=True)
class ChunkedRun:
    """A run made in compiled chunks (:func:`simulate_in_chunks`).

    **Fields:** ``state`` the final :class:`~jaxbelt.BeltState`; ``trajectory`` the records, as one
    call of :func:`simulate` makes them; ``fields`` (len(field_rows), n_xi, b) the full displacement
    at the requested record rows, or ``None``; ``compile_s``, ``run_s`` seconds spent compiling
    (with the run data) and running."""

    state: BeltState
    trajectory: Trajectory
    fields: np.ndarray | None
    compile_s: float
    run_s: float


def simulate_in_chunks(model: BeltModel, solver: AbstractIntegrator | None = None, *, n_steps: int, dt,
                       saveat: SaveAt = SaveAt(), adjoint: Checkpointed = Checkpointed(),
                       y0: BeltState | None = None, field_rows=None, progress: bool = True,
                       chunk: int = 200) -> ChunkedRun:
    """:func:`simulate` in compiled chunks of about ``chunk`` steps (whole record intervals), for
    long runs at the command line: a progress bar, compilation ahead of the run (timed apart), and
    the full field kept only at ``field_rows`` (record rows, in the order given, repeats allowed),
    so memory holds one chunk's fields, not the run's. The run data (factors) are computed once,
    so the records equal one :func:`simulate` call. Not traceable; no finiteness check.
    """
    from tqdm import tqdm

    solver = make_solver() if solver is None else solver
    n_steps = int(n_steps)
    check_time_step(model, dt)
    check_start_masses(model, solver, y0)
    dt = jnp.asarray(dt, dtype=model.ell.dtype)
    run_saveat = SaveAt(saveat.every, fields=saveat.fields or field_rows is not None)
    chunk = max(saveat.every, (chunk // saveat.every) * saveat.every)
    sizes = [min(chunk, n_steps - k) for k in range(0, n_steps, chunk)] or [0]
    t0 = time.perf_counter()
    state, run_data = jax.block_until_ready(_init_run(model, solver, y0, dt))
    compiled = {k: _simulate.lower(model, solver, state, dt, k, run_saveat, adjoint, run_data).compile()
                for k in sorted(set(sizes))}
    compile_s = time.perf_counter() - t0
    wanted, kept, parts, row0 = set(field_rows or ()), {}, [], 0
    t0 = time.perf_counter()
    with tqdm(total=n_steps, unit="step", disable=not progress, leave=False) as bar:
        for k in sizes:
            state, traj = compiled[k](model, solver, state, dt, k, run_saveat, adjoint, run_data)
            n_rec = traj.t.shape[0]
            for r in wanted:
                if row0 <= r < row0 + n_rec:
                    kept[r] = np.asarray(traj.u[r - row0])
            parts.append(traj if saveat.fields else dataclasses.replace(traj, u=None))
            row0 += n_rec
            bar.update(k)
    jax.block_until_ready(state.u)
    run_s = time.perf_counter() - t0
    traj = jax.tree.map(lambda *xs: jnp.concatenate(xs, axis=0), *parts)
    fields = None if field_rows is None else np.stack([kept[r] for r in field_rows])
    return ChunkedRun(state, traj, fields, compile_s, run_s)


def compile_simulation(model: BeltModel, solver: AbstractIntegrator | None = None, *, n_steps: int, dt,
                       saveat: SaveAt = SaveAt(), adjoint: Checkpointed = Checkpointed(), y0: BeltState | None = None):
    """:func:`simulate`'s compiled program, ahead of time (to time compilation apart from the run).

    **Returns:** ``run(model, dt) -> (final_state, Trajectory)`` for models of the same structure
    (any misalignment, material data or ``dt``); no finiteness check."""
    solver = make_solver() if solver is None else solver
    check_time_step(model, dt)
    dt = jnp.asarray(dt, dtype=model.ell.dtype)
    compiled = _simulate.lower(model, solver, y0, dt, int(n_steps), saveat, adjoint, None).compile()
    return lambda m, t: compiled(m, solver, y0, jnp.asarray(t, dtype=dt.dtype), int(n_steps), saveat, adjoint, None)


@functools.partial(jax.tree_util.register_dataclass, data_fields=["solver", "dt"],
                   meta_fields=["n_steps", "saveat", "adjoint"])
@dataclasses.dataclass(frozen=True)
class RunOptions:
    """A scene's own run settings, as :func:`simulate`'s keyword arguments.

    **Fields:** ``solver`` (from ``[solver]``), ``n_steps`` and ``dt`` (from ``[time]``), ``saveat``
    (from ``[output]``), ``adjoint`` the checkpointing of reverse mode through the run
    (:class:`Checkpointed`; a scene does not set it). A mapping, so ``simulate(model, **options)``
    works; :meth:`replace` changes some. The one way run settings travel: every function of the
    package that runs a model takes them as ``options``, and what keeps run settings (a
    :class:`~jaxbelt.design.Study`, a reduction's config) keeps a ``RunOptions``.

    A pytree: ``solver`` and ``dt`` are its leaves (a ``dt`` held as an array is traced, so runs at
    other time steps share compiled programs; a Python float stays static under
    :func:`equinox.filter_jit`), ``n_steps``, ``saveat`` and ``adjoint`` shape the program and are
    static."""

    solver: AbstractIntegrator
    n_steps: int
    dt: float
    saveat: SaveAt = SaveAt()
    adjoint: Checkpointed = Checkpointed()

    @classmethod
    def from_scene(cls, scene: Scene) -> "RunOptions":
        s = scene.solver
        return cls(make_solver(s.integrator, s.linear_solver, s.transport), scene.time.n_steps, scene.time.dt,
                   SaveAt(every=scene.output.every, fields=scene.output.fields == "full"))

    @property
    def t_end(self) -> float:
        """``n_steps × dt``, s."""
        return self.n_steps * self.dt

    def replace(self, **changes) -> "RunOptions":
        return dataclasses.replace(self, **changes)

    def keys(self):
        return ("solver", "n_steps", "dt", "saveat", "adjoint")

    def __getitem__(self, key):
        return getattr(self, key)
