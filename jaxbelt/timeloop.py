"""The time loop: solve → transport → outputs, as one jit-compiled ``lax.scan``.

``simulate`` is pure: ``jax.grad`` differentiates through the whole run (e.g. a tracer metric
w.r.t. ``model.chi_static``) and ``jax.vmap`` batches it over models that differ in array
fields (misalignments). Reverse mode costs about three forward runs
(``benchmarks/gradient_cost.py``): the step's linear solve has its own adjoint, which reuses the
step's factors (:func:`jaxbelt.linalg.bordered.solve_with_adjoint`), and the scan is
checkpointed in chunks of ``~√n`` steps, so memory grows as ``√n``, not ``n``, for one extra
forward pass. Outputs are scan outputs, decimated by ``model.every``; full fields are
only produced when the scene asks for them (``[output] fields = "full"``).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import lax

from .assembly import (free_belt_matvec, free_belt_stencil, generalised_belt_force, nodal_masses, roller_R,
                       static_surface_offset, stencil_matvec)
from .integrators import AbstractIntegrator, resolve_integrator
from .linalg import join
from .model import BeltModel
from .state import BeltState, initial_state
from .transport import transport_step_with_weights


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
    state) — evaluated inside the scan, read once at the end (:func:`check_finite`), no host sync
    per step;
    ``u`` (k, n_xi, b) or ``None``.
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


NONFINITE_CAUSES = {1: "belt displacement", 2: "belt velocity", 3: "roller state"}


class NonFiniteStateError(FloatingPointError):
    """The simulated state became NaN or infinite (the step, its time and which part)."""


def nonfinite_code(u, u_dot, chi, chi_dot):
    """0 if the state is finite, else the code (:data:`NONFINITE_CAUSES`) of its first bad part."""
    fin = lambda a: jnp.all(jnp.isfinite(a))  # noqa: E731
    return jnp.where(~fin(u), 1, jnp.where(~fin(u_dot), 2, jnp.where(~(fin(chi) & fin(chi_dot)), 3, 0))).astype(jnp.int8)


def first_nonfinite(traj: "Trajectory"):
    """``(k, t, cause)`` of the first recorded step whose state is not finite, or ``None``."""
    import numpy as np

    code = np.asarray(traj.nonfinite)
    bad = np.flatnonzero(code)
    if bad.size == 0:
        return None
    k = int(bad[0])
    return k, float(np.asarray(traj.t)[k]), NONFINITE_CAUSES[int(code[k])]


def check_finite(traj: "Trajectory", dt: float | None = None):
    """Raise :class:`NonFiniteStateError` naming the step, its time and the cause if the run's
    state became NaN/inf; nothing otherwise. Skipped (returns) when ``traj`` holds tracers (inside
    ``jit``/``grad``/``vmap`` the check belongs to the caller)."""
    if isinstance(traj.nonfinite, jax.core.Tracer):
        return
    hit = first_nonfinite(traj)
    if hit is not None:
        k, t, cause = hit
        step = round(t / dt) if dt else k + 1
        raise NonFiniteStateError(f"the simulation diverged: non-finite {cause} at step {step} (t = {t:g} s); "
                                  "check the time step against the CFL limit, the transport weights and the scene")


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
    the belt edge has left the roller's face (MODEL.md §1 requires belt ≤ roller width at rest;
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


def make_step(model: BeltModel, integrator: AbstractIntegrator, record_solved: bool = False):
    """``step(state) -> (state, record)``: one solve + transport with its outputs; with
    ``record_solved`` the record also holds the full pre-transport state ``x_solved``,
    ``v_solved`` (flat ``[belt; rollers]``), the snapshots of model order reduction, and the
    state after transport ``x_grid``, ``v_grid``."""
    p, d = model.n_rollers, len(model.dofs)
    integrator = integrator.prepare(model)
    stencil = free_belt_stencil(model)  # once per run, outside the scan
    offset = static_surface_offset(model)
    on = model.contact_columns  # R_r vanishes off the rollers: the loads need those columns only

    def roller_loads(state, solved):
        """``M_r χ̈ + Σ R_rᵀ f_k - Q_ext`` per roller DOF (§4 post-processing): at a prescribed DOF
        the force/torque its support must supply (what holds a misaligned roller, what the drive
        delivers); at a dynamic DOF the residual of its equation (≈ 0). The nodal forces ``f_k``
        are evaluated on the roller columns only (``model.contact_columns``), where ``R_r`` is
        non-zero."""
        a_u = (solved.u_dot - state.u_dot) / model.dt
        a_chi = (solved.chi_dot - state.chi_dot) / model.dt
        m = nodal_masses(model, state.m_e)
        if on is None or stencil is None:
            Kf_u = free_belt_matvec(model, solved.u) if stencil is None else stencil_matvec(stencil, solved.u)
            f = m * a_u + Kf_u + model.f0
            return model.M_roller * a_chi + generalised_belt_force(roller_R(model, state.u), f) - model.Q_ext
        idx = jnp.asarray(on, int)
        f = m[idx] * a_u[idx] + stencil_matvec(stencil, solved.u, on) + model.f0[idx]
        return model.M_roller * a_chi + generalised_belt_force(roller_R(model, state.u, on_rollers=True), f) \
            - model.Q_ext

    def step(state: BeltState):
        solved = integrator.solve_step(model, state)
        u, ud, chi, m_e, weights = transport_step_with_weights(model, solved.u, solved.u_dot, solved.chi, state.m_e,
                                                               static_offset=offset)
        new = BeltState(u=u, u_dot=ud, chi=chi, chi_dot=solved.chi_dot, m_e=m_e, step=state.step + 1)
        tu, tv = tracer_values(model, u)
        rec = dict(
            t=(state.step + 1) * model.dt,
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
        )
        if model.full_fields:
            rec["u"] = u
        if record_solved:
            rec["x_solved"] = join(solved.u, solved.chi)
            rec["v_solved"] = join(solved.u_dot, solved.chi_dot)
            rec["x_grid"] = join(new.u, new.chi)
            rec["v_grid"] = join(new.u_dot, new.chi_dot)
        return new, rec

    return step


def _checkpointed_scan(body, carry, length: int, chunk: int):
    """``lax.scan(body, carry, None, length=length)`` in chunks of ``chunk`` iterations, each
    chunk under ``jax.checkpoint``: reverse mode keeps only the carries at chunk boundaries and
    recomputes one chunk at a time (one extra forward pass, memory ∝ ``length / chunk`` carries
    + ``chunk`` steps' residuals). A loop no longer than ``chunk`` is a plain scan. Outputs
    (``None`` allowed) are stacked as by one scan; a forward-only run computes the same."""
    if length <= chunk:
        return lax.scan(body, carry, None, length=length)

    def part(k, in_scan):  # inside a scan XLA cannot CSE the recomputation away
        return jax.checkpoint(lambda c: lax.scan(body, c, None, length=k), prevent_cse=not in_scan)

    n_chunks, rem = divmod(length, chunk)
    carry, ys = lax.scan(lambda c, _: part(chunk, True)(c), carry, None, length=n_chunks)
    ys = jax.tree.map(lambda a: a.reshape(n_chunks * chunk, *a.shape[2:]), ys)
    if rem:
        carry, ys_rem = part(rem, False)(carry)
        ys = jax.tree.map(lambda a, b: jnp.concatenate([a, b]), ys, ys_rem)
    return carry, ys


def default_checkpoint_chunk(n_steps: int) -> int:
    """Steps per checkpointed chunk of :func:`run`: ``⌈√n⌉``, so reverse-mode memory grows as
    ``√n`` (``√n`` carries and ``√n`` steps' residuals), at the price of one extra forward pass."""
    return max(1, math.isqrt(max(n_steps - 1, 0)) + 1)


def run(model: BeltModel, integrator: AbstractIntegrator, state: BeltState, n_steps: int,
        checkpoint: int | None = None):
    """``n_steps`` steps from ``state``; records every ``model.every``-th step.

    The loop is a two-level scan: chunks of ``checkpoint`` steps (default
    :func:`default_checkpoint_chunk`; ``0``: none) under ``jax.checkpoint``, so reverse mode
    through a long run stays in bounded memory; the forward result is the same.

    **Returns:** ``(final_state, Trajectory)``.
    """
    step = make_step(model, integrator)
    every = model.every
    n_out, tail = divmod(n_steps, every)
    chunk = default_checkpoint_chunk(n_steps) if checkpoint is None else (checkpoint or n_steps)
    advance = lambda s, _: (step(s)[0], None)

    def record(s, _):
        s = _checkpointed_scan(advance, s, every - 1, chunk)[0] if every > 1 else s
        return step(s)

    state, rec = _checkpointed_scan(record, state, n_out, max(1, chunk // every))
    if tail:
        state = _checkpointed_scan(advance, state, tail, chunk)[0]
    return state, Trajectory(u=rec.pop("u", None), **rec)


@eqx.filter_jit
def _run_jit(model, integrator, state, n_steps, checkpoint=None):
    return run(model, integrator, state, n_steps, checkpoint)


def simulate(model: BeltModel, integrator: AbstractIntegrator | str | None = None,
             state: BeltState | None = None, n_steps: int | None = None, checkpoint: int | None = None,
             check: bool = True):
    """Simulate a compiled model (jit-compiled; differentiable; vmap-able over array fields).

    **Arguments:**
    - ``model``: from :func:`jaxbelt.compile_scene`.
    - ``integrator``: an integrator, its name (``"naive" | "direct" | "eliminated"``) or
      ``None`` for the scene's choice.
    - ``state``: start state; default :func:`jaxbelt.initial_state` (static equilibrium).
    - ``n_steps``: default ``model.n_steps`` (``t_end / dt``).
    - ``checkpoint``: steps per checkpointed chunk for reverse mode (:func:`run`); default
      ``⌈√n_steps⌉``, ``0`` for none.
    - ``check``: raise :class:`NonFiniteStateError` (step, time, cause) if the state became
      NaN/inf — a flag computed inside the scan and read once here; skipped under
      ``jit``/``grad``/``vmap``, where ``Trajectory.nonfinite`` carries it to the caller.

    **Returns:** ``(final_state, Trajectory)``.
    """
    integrator = resolve_integrator(integrator, model)
    if state is None:
        state = initial_state(model)
    out = _run_jit(model, integrator, state, int(model.n_steps if n_steps is None else n_steps), checkpoint)
    if check:
        check_finite(out[1], model.dt)
    return out


def simulate_with_progress(model: BeltModel, integrator=None, n_steps: int | None = None,
                           chunk: int = 200, progress: bool = True, check: bool = True):
    """:func:`simulate` in jit-compiled chunks with a progress bar (for the CLI and long runs).

    Chunks are whole multiples of ``model.every``; the result equals one :func:`simulate` call
    (``check`` as there).
    Compilation is done ahead of the run so the two can be timed apart.

    **Returns:** ``(final_state, Trajectory, timing)`` with ``timing = {"compile_s", "run_s"}``.
    """
    import time

    from tqdm import tqdm

    integrator = resolve_integrator(integrator, model)
    n_steps = int(model.n_steps if n_steps is None else n_steps)
    chunk = max(model.every, (chunk // model.every) * model.every)
    state = initial_state(model)
    sizes = [min(chunk, n_steps - k) for k in range(0, n_steps, chunk)]
    t0 = time.perf_counter()
    compiled = {k: _run_jit.lower(model, integrator, state, k).compile() for k in sorted(set(sizes))}
    compile_s = time.perf_counter() - t0
    parts = []
    t0 = time.perf_counter()
    with tqdm(total=n_steps, unit="step", disable=not progress, leave=False) as bar:
        for k in sizes:
            state, traj = compiled[k](model, integrator, state, k)
            jax.block_until_ready(state.u)
            parts.append(traj)
            bar.update(k)
    run_s = time.perf_counter() - t0
    traj = jax.tree.map(lambda *xs: jnp.concatenate(xs, axis=0), *parts)
    if check:
        check_finite(traj, model.dt)
    return state, traj, {"compile_s": compile_s, "run_s": run_s}
