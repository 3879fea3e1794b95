"""Belt steering loops: an edge sensor, a sampled PID controller and a tilting roller.

A real precision belt is held laterally by a *steering roller*: a sensor reads the belt edge at
a point fixed in the machine and a controller tilts one roller, which makes the belt walk back.
Here the loop is part of the machine (``[[control]]`` tables of a scene, :class:`SteeringLoops`
in :attr:`jaxbelt.model.BeltModel.control`) and its state rides in the time loop's carry
(:class:`ControllerState` in :class:`jaxbelt.state.BeltState`). All of it is ``jnp``: a closed-loop
run is jit-compiled, differentiable in the gains and the misalignments, and vmap-able over both.

One step of the closed loop, from the state at ``t_k`` (step ``k``):

1. **Sensor** (:func:`measure`): the belt's lateral displacement ``v`` at the sensor point
   ``(s, z)`` (bilinear in the element, as a tracer), plus the belt edge's own waviness
   ``Σ a_h sin(2π h ξ / L + φ_h)`` at the material coordinate ``ξ = s − travel`` that passes the
   sensor (fixed in the material, seen once per loop), plus Gaussian noise ``σ`` drawn from
   ``fold_in(key(seed), k)``.
2. **Controller** (:func:`controller_update`), at the sample instants ``k ≡ 0 (mod n_s)``,
   ``n_s = sample_s / Δt``, ``T_s = n_s Δt``, zero-order hold between them. With the error
   ``e = y − setpoint``: ``I ← I + k_i T_s e``, ``w = k_p e + I + k_d (e − e_prev) / T_s``, clipped
   to the range ``±limit``. Anti-windup by conditional integration: the integral does not grow
   while ``w`` is beyond the range in the direction it would grow, and ``|I| ≤ limit``, so a
   saturated loop recovers as soon as the error turns. The command is
   ``u_c = −sign · w_sat``: gains are magnitudes and ``sign`` is the sign of the machine's steering
   coefficient (walk rate per actuator rotation, :func:`jaxbelt.lateral_theory.scene_walk_rate`
   at build time), so positive gains always act against the error.
3. **Actuator**: first-order lag ``τ u̇ = u_c − u`` by Backward Euler,
   ``u ← u + Δt / (τ + Δt) (u_c − u)``, then the rate limit, ``|Δu| ≤ r Δt``.
4. The step from ``t_k`` to ``t_{k+1}`` runs with the actuator roller's rotation at its static
   value plus ``u``: a prescribed DOF that changes with time. The no-slip rows hold
   ``χ(t_{k+1}) − χ(t_k)``, so its *rate* moves the belt on the roller (model specification §2), and
   the transport step carries the belt relative to the tilted surface.

Decisions where the specification is silent: the derivative acts on the sampled error (no
filter; ``k_d = 0`` by default), the first sample takes the initial error as ``e_prev`` (no
derivative kick at start); the belt's travel (for the edge profile) is the accumulated shift of
the transport step, so it is the material's own label, not ``V t``.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np


class SteeringLoops(eqx.Module):
    """The ``n_c`` steering loops of a machine, SI units. Array fields are (n_c,) unless noted,
    pytree leaves (``jax.grad``/``jax.vmap`` reach the gains and limits).

    **Fields:** ``actuator_dof`` (static) flat roller-DOF index of each actuated rotation;
    ``labels`` (static) ``"roller name/axis"``; ``sensor_col``, ``sensor_xi``, ``sensor_row``,
    ``sensor_eta`` the sensor point's element and local coordinates; ``sensor_s`` its position
    along the path (m); ``kp`` rad/m, ``ki`` rad/(m s), ``kd`` rad s/m; ``sign`` ±1, the sign of
    the steering coefficient; ``sample`` s; ``limit`` rad; ``rate_limit`` rad/s (inf: none);
    ``lag`` s; ``setpoint`` m; ``noise`` m (σ); ``key`` (n_c, 2) uint32 noise keys;
    ``profile_harmonic``, ``profile_amplitude`` (m), ``profile_phase`` (rad), each (n_c, n_h),
    the edge profile (zero amplitude pads); ``loop_length`` () the belt path length, m.
    """

    sensor_col: jax.Array
    sensor_xi: jax.Array
    sensor_row: jax.Array
    sensor_eta: jax.Array
    sensor_s: jax.Array
    kp: jax.Array
    ki: jax.Array
    kd: jax.Array
    sign: jax.Array
    sample: jax.Array
    limit: jax.Array
    rate_limit: jax.Array
    lag: jax.Array
    setpoint: jax.Array
    noise: jax.Array
    key: jax.Array
    profile_harmonic: jax.Array
    profile_amplitude: jax.Array
    profile_phase: jax.Array
    loop_length: jax.Array
    actuator_dof: tuple = eqx.field(static=True)
    labels: tuple = eqx.field(static=True)

    @property
    def n_loops(self) -> int:
        return len(self.actuator_dof)

    def with_gains(self, kp=None, ki=None, kd=None) -> "SteeringLoops":
        """Copy with gains replaced (arrays (n_c,) or scalars; ``None`` keeps)."""
        new = {k: jnp.broadcast_to(jnp.asarray(v, self.kp.dtype), self.kp.shape)
               for k, v in (("kp", kp), ("ki", ki), ("kd", kd)) if v is not None}
        return eqx.tree_at(lambda s: tuple(getattr(s, k) for k in new), self, tuple(new.values()))


class ControllerState(eqx.Module):
    """The controllers' state between two steps, (n_c,) each: ``integral`` (rad), ``error`` the
    last sampled error (m), ``command`` the held command (rad), ``angle`` the actuator angle
    applied in the last step (rad); ``travel`` () the belt's accumulated travel (m)."""

    integral: jax.Array
    error: jax.Array
    command: jax.Array
    angle: jax.Array
    travel: jax.Array


def sensor_displacement(loops: SteeringLoops, u) -> jax.Array:
    """The belt's lateral displacement ``v`` (n_c,) at the sensor points, m, for a 2D belt field
    ``u`` (n_xi, 2 n_eta): bilinear in the sensor's element."""
    v = u[:, 1::2]
    c, xi, r, e = loops.sensor_col, loops.sensor_xi, loops.sensor_row, loops.sensor_eta
    c1 = (c + 1) % v.shape[0]
    return ((1 - xi) * (1 - e) * v[c, r] + (1 - xi) * e * v[c, r + 1]
            + xi * (1 - e) * v[c1, r] + xi * e * v[c1, r + 1])


def edge_profile(loops: SteeringLoops, travel) -> jax.Array:
    """The belt edge's own lateral waviness (n_c,) passing the sensors after ``travel`` m."""
    xi = loops.sensor_s - travel
    arg = 2 * jnp.pi * loops.profile_harmonic * xi[:, None] / loops.loop_length + loops.profile_phase
    return jnp.sum(loops.profile_amplitude * jnp.sin(arg), axis=1)


def measure(loops: SteeringLoops, u, travel, step) -> jax.Array:
    """What the sensors read (n_c,), m: belt displacement + edge profile + noise (module docstring)."""
    keys = jax.vmap(lambda k: jax.random.fold_in(jax.random.wrap_key_data(k), step))(loops.key)
    noise = jax.vmap(lambda k: jax.random.normal(k, (), loops.noise.dtype))(keys)
    return sensor_displacement(loops, u) + edge_profile(loops, travel) + loops.noise * noise


def samples_per_update(loops: SteeringLoops, dt) -> jax.Array:
    """``n_s = sample / Δt`` (n_c,) int, at least 1."""
    return jnp.maximum(jnp.round(loops.sample / dt), 1).astype(jnp.int32)


def initial_controller_state(loops: SteeringLoops, u) -> ControllerState:
    """At rest: no integral, no command, the actuator at its static value; ``error`` the
    sensor's noise-free reading of the initial state (so the first derivative has no kick)."""
    zero = jnp.zeros_like(loops.kp)
    e0 = sensor_displacement(loops, u) + edge_profile(loops, jnp.zeros(())) - loops.setpoint
    return ControllerState(integral=zero, error=e0, command=zero, angle=zero, travel=jnp.zeros((), zero.dtype))


def controller_update(loops: SteeringLoops, state: ControllerState, reading, step, dt):
    """One step of the controllers and actuators (module docstring, 2–3).

    **Arguments:** ``reading`` (n_c,) the sensors' output at the state of step ``step``; ``dt`` s.
    **Returns:** ``(state, angle)``: the new controller state and the actuator angles (n_c,),
    rad, to apply in the step that follows (added to the actuated rotations' static values).
    """
    n_s = samples_per_update(loops, dt)
    Ts = n_s * dt
    sample_now = jnp.mod(step, n_s) == 0
    e = reading - loops.setpoint
    pd = loops.kp * e + loops.kd * (e - state.error) / Ts
    step_i = loops.ki * Ts * e
    w_try = pd + state.integral + step_i
    winding = (jnp.abs(w_try) > loops.limit) & (step_i * w_try > 0)  # integrating would push further out
    integral = jnp.clip(jnp.where(winding, state.integral, state.integral + step_i), -loops.limit, loops.limit)
    w_sat = jnp.clip(pd + integral, -loops.limit, loops.limit)
    command = -loops.sign * w_sat
    integral = jnp.where(sample_now, integral, state.integral)
    error = jnp.where(sample_now, e, state.error)
    command = jnp.where(sample_now, command, state.command)
    lagged = state.angle + dt / (loops.lag + dt) * (command - state.angle)
    angle = state.angle + jnp.clip(lagged - state.angle, -loops.rate_limit * dt, loops.rate_limit * dt)
    new = ControllerState(integral=integral, error=error, command=command, angle=angle, travel=state.travel)
    return new, angle


def walk_rate(t, v, window):
    """The walk rate of a lateral signal: the least-squares slope of ``v`` (…, n) over the times
    ``t`` (n,) on the samples with ``window[0] ≤ t ≤ window[1]`` (s), in the units of ``v`` per s.
    ``jnp`` (traceable, the window too); the one definition every walk rate read off a run uses."""
    t = jnp.asarray(t)
    v = jnp.asarray(v)
    w = ((t >= window[0]) & (t <= window[1])).astype(t.dtype)
    t_mean = jnp.sum(w * t) / jnp.sum(w)
    tc = (t - t_mean) * w
    v_mean = jnp.sum(v * w, axis=-1, keepdims=True) / jnp.sum(w)
    return jnp.sum((v - v_mean) * tc, axis=-1) / jnp.sum(tc * tc)


SATURATION_FRACTION = 0.999  # an actuator at this fraction of its range counts as saturated


def loop_summary(loops: SteeringLoops, control_u, sensor_v, t=None) -> list[dict]:
    """Per loop, from a run's records (``Trajectory.control_u``/``sensor_v``, (k, n_c)):
    ``actuator``, ``axis``, ``sensor_um_final`` (the belt's lateral displacement at the sensor at
    the end, µm), ``u_mrad_final``, ``u_mrad_max`` (largest |angle|), ``limit_mrad``,
    ``saturated`` (the actuator reached ``SATURATION_FRACTION`` of its range at some step) and
    ``saturated_fraction`` (of the recorded steps). With ``t`` (k,) also ``sensor_walk_um_s``: the
    least-squares slope of the sensor signal over the last quarter of the run (a saturated loop
    cannot stop the walk)."""
    u, y = np.asarray(control_u), np.asarray(sensor_v)
    limit = np.asarray(loops.limit)
    out = []
    for i, label in enumerate(loops.labels):
        actuator, axis = label.rsplit("/", 1)
        at_limit = np.abs(u[:, i]) >= SATURATION_FRACTION * limit[i]
        row = dict(actuator=actuator, axis=axis, sensor_um_final=float(y[-1, i] * 1e6),
                   u_mrad_final=float(u[-1, i] * 1e3), u_mrad_max=float(np.max(np.abs(u[:, i])) * 1e3),
                   limit_mrad=float(limit[i] * 1e3), saturated=bool(at_limit.any()),
                   saturated_fraction=float(at_limit.mean()))
        if t is not None and len(t) >= 8:
            tt = np.asarray(t)
            row["sensor_walk_um_s"] = float(walk_rate(tt, y[:, i], (tt[-(len(tt) // 4)], tt[-1])) * 1e6)
        out.append(row)
    return out
