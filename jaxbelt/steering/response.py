"""The full model's open-loop response of a steering loop as a transfer
(:class:`~jaxbelt.steering.transfer.Transfer`), in continuous time (:class:`MeasuredResponse`) and
as the sampled loop (:class:`DiscreteLoop`), and the one way a step of the actuator is applied
(:func:`actuator_step`): the controller saturated (``k_p = 1``, a setpoint a metre away, the
range set to the step), so the angle is held at the step from the first sample on, through the
actuator's lag (its rate limit lifted: the identified plant is the linear one), with sensor noise
and edge profile off (they act on the reading only, which the saturated controller ignores)."""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..control import SteeringLoops


def actuator_step(loops: SteeringLoops, amplitude: float, loop: int = 0) -> SteeringLoops:
    """``loops`` with loop ``loop`` saturated to hold the angle ``amplitude`` rad from ``t = 0``
    (module docstring) and every other loop open (gains 0)."""
    one = jnp.zeros_like(loops.kp).at[loop].set(1.0)
    return eqx.tree_at(lambda s: (s.kp, s.ki, s.kd, s.sign, s.setpoint, s.limit, s.rate_limit, s.noise,
                                  s.profile_amplitude),
                       loops, (one, 0 * loops.ki, 0 * loops.kd, -jnp.ones_like(loops.sign), -one,
                               jnp.full_like(loops.kp, amplitude), jnp.full_like(loops.kp, jnp.inf), 0 * loops.noise,
                               0 * loops.profile_amplitude))


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
