"""The steering plant as a low-order transfer function: what a loop designer works with.

The belt's lateral response at an edge sensor to the steering roller's angle is, in the string
limit (Shelton's first-order span model), an integrator — a steady angle walks the belt at a
steady rate, the *steering coefficient* — behind the span's first-order lag and the transport
delay from the steering roller to the sensor. jaxbelt identifies that form from the full
model's open-loop step response (:mod:`jaxbelt.design.steering`):

    G(s) = k e^{−θ s} / (s (1 + τ s))

with ``k`` the coefficient (m/s per rad), ``τ`` the lag (s) and ``θ`` the delay (s). The sign
of ``k`` is the loop's sign; a controller ``C(s) = k_p + k_i / s + k_d s`` acts through
``−sign(k)``, so the loop transfer is ``L(s) = |k| … C(s)`` (:mod:`jaxbelt.control`).
"""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class SteeringPlant:
    """``G(s) = k e^{−θ s} / (s (1 + τ s))`` (module docstring).

    **Fields:** ``gain`` ``k``, m/s per rad (signed); ``lag`` ``τ``, s; ``delay`` ``θ``, s."""

    gain: float
    lag: float
    delay: float

    def frequency_response(self, omega):
        """``G(iω)`` for angular frequencies ``omega`` (rad/s), complex."""
        s = 1j * np.asarray(omega, float)
        return self.gain * np.exp(-self.delay * s) / (s * (1.0 + self.lag * s))

    def step_response(self, t, amplitude: float = 1.0):
        """Sensor displacement (m) at times ``t`` (s) after a step of ``amplitude`` rad at ``t = 0``:
        ``k a (t' − τ (1 − e^{−t'/τ}))``, ``t' = max(t − θ, 0)``."""
        tp = np.maximum(np.asarray(t, float) - self.delay, 0.0)
        lagged = self.lag * -np.expm1(-tp / self.lag) if self.lag > 0 else 0.0 * tp
        return self.gain * amplitude * (tp - lagged)

    def loop_response(self, omega, kp, ki=0.0, kd=0.0):
        """The loop transfer ``L(iω) = |G(iω)| … C(iω)`` with the loop's sign folded in (complex)."""
        s = 1j * np.asarray(omega, float)
        return abs(self.gain) / self.gain * self.frequency_response(omega) * (kp + ki / s + kd * s)

    def margins(self, kp, ki=0.0, kd=0.0, omega=None):
        """``(gain_margin, phase_margin_deg, omega_pc, omega_gc)`` of the loop with a PID
        controller (gains in SI: rad/m, rad/(m s), rad s/m). Found on a log grid refined by
        bisection; ``inf`` where the curve does not cross."""
        w = np.logspace(-4, 3, 4000) if omega is None else np.asarray(omega, float)
        L = self.loop_response(w, kp, ki, kd)
        mag, ph = np.abs(L), np.unwrap(np.angle(L))
        gm, w_pc = np.inf, np.nan
        cross = np.flatnonzero((ph[:-1] + np.pi) * (ph[1:] + np.pi) <= 0)
        if cross.size:
            i = cross[0]
            w_pc = _refine(lambda x: np.unwrap(np.angle(self.loop_response(np.array([w[i], x]), kp, ki, kd)))[1] + np.pi,
                           w[i], w[i + 1])
            gm = 1.0 / abs(self.loop_response(np.array([w_pc]), kp, ki, kd)[0])
        pm, w_gc = np.inf, np.nan
        cross = np.flatnonzero((mag[:-1] - 1.0) * (mag[1:] - 1.0) <= 0)
        if cross.size:
            i = cross[0]
            w_gc = _refine(lambda x: abs(self.loop_response(np.array([x]), kp, ki, kd)[0]) - 1.0, w[i], w[i + 1])
            phase = np.unwrap(np.angle(self.loop_response(np.array([w[i], w_gc]), kp, ki, kd)))[1]
            pm = float(np.degrees(phase + np.pi))
        return float(gm), float(pm), float(w_pc), float(w_gc)


def _refine(f, a, b, iters: int = 60):
    """Bisection of a sign change of ``f`` in ``[a, b]`` (log-spaced)."""
    fa = f(a)
    for _ in range(iters):
        m = np.sqrt(a * b)
        fm = f(m)
        if fa * fm <= 0:
            b = m
        else:
            a, fa = m, fm
    return np.sqrt(a * b)
