"""The full model's open-loop response of a steering loop: the one measured step response
(:func:`open_loop_response`, the runs behind every plant of :mod:`jaxbelt.steering`), as a transfer
(:class:`~jaxbelt.steering.transfer.Transfer`) in continuous time (:class:`MeasuredResponse`) and
as the sampled loop (:class:`DiscreteLoop`); the runs of a batch of loop settings side by side
(:func:`run_batch`); and the one way a step of the actuator is applied
(:func:`actuator_step`): the controller saturated (``k_p = 1``, a setpoint a metre away, the
range set to the step), so the angle is held at the step from the first sample on, through the
actuator's lag (its rate limit lifted: the identified plant is the linear one), with sensor noise
and edge profile off (they act on the reading only, which the saturated controller ignores)."""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..control import SteeringLoops, walk_rate
from ..infra.programs import stored_jit
from ..model import BeltModel
from ..timeloop import RunOptions, simulate

STEP_RAD = 1e-4  # the actuator step of the measured response, rad (0.1 mrad: the linear range)
WALK_WINDOW_S = 5.0  # the measured response's walk rate: the slope over the run's last seconds


def actuator_step(loops: SteeringLoops, amplitude: float, loop: int = 0) -> SteeringLoops:
    """``loops`` with loop ``loop`` saturated to hold the angle ``amplitude`` rad from ``t = 0``
    (module docstring) and every other loop open (gains 0)."""
    one = jnp.zeros_like(loops.kp).at[loop].set(1.0)
    return eqx.tree_at(lambda s: (s.kp, s.ki, s.kd, s.sign, s.setpoint, s.limit, s.rate_limit, s.noise,
                                  s.profile_amplitude),
                       loops, (one, 0 * loops.ki, 0 * loops.kd, -jnp.ones_like(loops.sign), -one,
                               jnp.full_like(loops.kp, amplitude), jnp.full_like(loops.kp, jnp.inf), 0 * loops.noise,
                               0 * loops.profile_amplitude))


def open_loops(model: BeltModel) -> BeltModel:
    """``model`` with every steering loop open (gains 0: the actuator angle stays 0)."""
    return model.replace(control=model.control.with_gains(0.0, 0.0, 0.0))


@stored_jit
def _batch_sensor(models, solver, n_steps, dt, loop):
    """Sensor displacement and actuator angle of loop ``loop`` for a stacked batch of models."""
    def one(m):
        _, tr = simulate(m, solver, n_steps=n_steps, dt=dt, check=False)
        return tr.t, tr.sensor_v[:, loop], tr.control_u[:, loop], tr.edge_margin
    return jax.vmap(one, in_axes=(_axes(models),))(models)


def _axes(models):
    return jax.tree.map(lambda a: 0 if eqx.is_array(a) else None, models)


def _stack(models):
    arrays = [eqx.filter(m, eqx.is_array) for m in models]
    static = eqx.filter(models[0], eqx.is_array, inverse=True)
    stacked = jax.tree.map(lambda *xs: jnp.stack(xs), *arrays)
    return eqx.combine(stacked, static)


def run_batch(models, options: RunOptions, loop: int = 0):
    """Closed- or open-loop runs of a list of models that differ in array values only (one vmapped
    program), ``options.n_steps`` steps of ``options.dt`` with ``options.solver``: ``(t (n,),
    sensor_v (b, n) m, control_u (b, n) rad, edge_margin (b, n, p) m)`` of loop ``loop``."""
    t, v, u, em = _batch_sensor(_stack(models), options.solver, int(options.n_steps), float(options.dt), loop)
    return np.asarray(t[0]), np.asarray(v), np.asarray(u), np.asarray(em)


def open_loop_response(model: BeltModel, options: RunOptions, *, amplitude: float = STEP_RAD, loop: int = 0,
                       t_end: float | None = None) -> "MeasuredResponse":
    """The measured step response of loop ``loop`` (:class:`MeasuredResponse`), the one every plant
    of the package is read from: two runs from the static state in one batch (:func:`run_batch`),
    every loop open (:func:`open_loops`), one of them with the actuator angle stepped to
    ``amplitude`` rad at ``t = 0`` (:func:`actuator_step`, so the actuator's lag is part of the
    response); their difference over the amplitude, so the scene's own disturbance cancels. The run
    is ``options``' (``t_end`` s instead where given); it should be long enough for the
    once-around echoes to die out (tens of seconds) where the response is read as a transfer: its
    ``rate`` is the walk rate over the last :data:`WALK_WINDOW_S` s (:func:`jaxbelt.control.walk_rate`)."""
    if t_end is not None:
        options = options.replace(n_steps=int(round(t_end / options.dt)))
    opened = open_loops(model)
    stepped = opened.replace(control=actuator_step(opened.control, amplitude, loop))
    t, v, _, _ = run_batch([opened, stepped], options, loop)
    step = (v[1] - v[0]) / amplitude
    rate = float(walk_rate(t, step, (t[-1] - WALK_WINDOW_S, t[-1])))
    return MeasuredResponse(t=t, step=step, dt=float(options.dt), rate=rate)


@dataclasses.dataclass(frozen=True)
class MeasuredResponse:
    """The full model's open-loop response of the sensor to the actuator angle, continuous time.

    **Fields:** ``t`` (n,) s, the record times; ``step`` (n,) m per rad, the sensor displacement
    after a unit step of the actuator angle at ``t = 0`` (the run with the step minus the run
    without, so the scene's own disturbance cancels); ``dt`` s; ``rate`` m/s per rad, the final
    walk rate (the integrator's gain, signed)."""

    t: np.ndarray
    step: np.ndarray
    dt: float
    rate: float

    @property
    def sign(self) -> float:
        return float(np.sign(self.rate))

    def frequency_response(self, omega):
        """``G(iω)`` (complex): ``rate / (iω) + Σ_j (h_j − rate) e^{−iω t_j} Δt`` with ``h_j`` the
        step response's increments per Δt; exact for the sampled record where the response has
        settled to a steady walk before its end."""
        w = np.asarray(omega, float)
        h = np.diff(np.concatenate([[0.0], self.step])) / self.dt - self.rate
        tj = np.arange(h.size) * self.dt
        return self.rate / (1j * w) + np.exp(-1j * np.outer(w, tj)) @ h * self.dt

    def frequency_grid(self):
        """3000 log-spaced angular frequencies from 1e-3 rad/s to the Nyquist frequency ``π / dt``."""
        return np.logspace(-3, np.log10(np.pi / self.dt), 3000)


@dataclasses.dataclass(frozen=True)
class DiscreteLoop:
    """The sampled loop's plant ``P(e^{iω T_s})`` from the model's own unit step response, no
    fitted form.

    **Fields:** ``response`` (n,) m per rad at ``t_k = k Δt``, ``k = 1 … n`` (the runs' records;
    the angle steps at ``t = 0``); ``gain`` the steady coefficient ``k`` (m/s per rad); ``dt`` s;
    ``sample_steps`` the controller's sample period in steps, ``T_s = sample_steps Δt``.

    With the samples ``y_m = y(m T_s)``, ``y_0 = 0``, the pulse response ``h_m = y_m − y_{m−1}``
    tends to ``h_∞ = k T_s`` (the integrator), so

        P(z) = Σ_{m=1}^{M} (h_m − h_∞) z^{−m} + h_∞ z^{−1} / (1 − z^{−1})

    (the first sum converges once the laps' transient has died out within the run). A loop
    ``u_m = −C y_m`` through the hold is then exactly ``1 + C P(z) = 0``: the open-loop step
    response already holds the one-step lag, so no hold delay is added
    (:func:`~jaxbelt.steering.transfer.loop_response` with ``sample_delay = 0``; a PI or PID
    controller enters through its continuous response ``C(iω)``, exact for P)."""

    response: np.ndarray
    gain: float
    dt: float
    sample_steps: int = 1

    @property
    def sign(self) -> float:
        return float(np.sign(self.gain))

    def frequency_response(self, omega):
        y = np.asarray(self.response, float)[self.sample_steps - 1::self.sample_steps]
        Ts = self.sample_steps * float(self.dt)
        h = np.diff(np.concatenate([[0.0], y]))
        h_inf = float(self.gain) * Ts
        zi = np.exp(-1j * np.asarray(omega, float)[..., None] * Ts)  # z^{-1}
        m = np.arange(1, len(h) + 1)
        return ((h - h_inf) * zi ** m).sum(-1) + h_inf * zi[..., 0] / (1.0 - zi[..., 0])

    def frequency_grid(self):
        """4000 log-spaced angular frequencies from ``1e-3 / T_s`` to just below the Nyquist
        frequency ``π / T_s``."""
        Ts = self.sample_steps * float(self.dt)
        return np.geomspace(1e-3 / Ts, np.pi / Ts * 0.999, 4000)


def response_transfer(response, gain, dt, omega, sample_steps: int = 1):
    """``P(e^{iω T_s})`` of :class:`DiscreteLoop` at ``omega`` (a shorthand)."""
    return DiscreteLoop(np.asarray(response, float), float(gain), float(dt), int(sample_steps)).frequency_response(omega)
