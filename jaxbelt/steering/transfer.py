"""One transfer abstraction for a steering loop's plant, and its margins.

A loop designer meets the plant in three descriptions, and every one of them answers the same
question, ``G(iω)``:

- the identified plant (:class:`~jaxbelt.steering.plant.SteeringPlant`, a low-order form fitted to
  the model's step response);
- the measured response (:class:`~jaxbelt.steering.response.MeasuredResponse`: the model's step
  response as a Fourier sum, continuous time);
- the discrete loop (:class:`~jaxbelt.steering.response.DiscreteLoop`: the sampled loop on the step
  response's samples, ``P(e^{iωT_s})``, no fitted form).

A :class:`Transfer` has ``frequency_response(ω)``, the loop's ``sign`` (the sign of its steady
walk per actuator angle: the controller acts through ``−sign``) and ``frequency_grid()`` (where its
crossings are searched). :func:`loop_response` closes it with a PID controller (and the sampled
loop's own hold delay), :func:`margins` gives the gain and phase margins of any of them, by one
method: the crossings located on the grid and each refined by bisection, the smallest margin over
every crossing (a recirculating plant crosses once per lap), as python-control's
``stability_margins`` takes them.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np


class Transfer(Protocol):
    """What :func:`margins` needs of a plant description (module docstring)."""

    sign: float

    def frequency_response(self, omega) -> np.ndarray:
        """``G(iω)`` at the angular frequencies ``omega`` (rad/s), complex."""

    def frequency_grid(self) -> np.ndarray:
        """The angular frequencies (rad/s, increasing) its crossings are searched on."""


def pid_response(w, kp, ki=0.0, kd=0.0):
    """``C(iω) = k_p + k_i / (iω) + k_d iω`` of the PID law at the angular frequencies ``w``."""
    s = 1j * np.asarray(w, float)
    return kp + ki / s + kd * s


def loop_response(transfer: Transfer, omega, kp, ki=0.0, kd=0.0, sample_delay=0.0):
    """``L(iω) = sign · G(iω) · C(iω) · e^{−iω d}`` (complex): the loop with its sign folded in,
    the controller's gains in SI (rad/m, rad/(m s), rad s/m), ``d = sample_delay`` s the sampled
    loop's own delay beyond the plant (the zero-order hold's ``T_s / 2`` for a continuous plant:
    :func:`jaxbelt.steering.report.sampling_delay`; 0 for the discrete loop, whose samples hold it)."""
    w = np.asarray(omega, float)
    hold = np.exp(-1j * w * sample_delay) if sample_delay else 1.0
    return transfer.sign * transfer.frequency_response(w) * pid_response(w, kp, ki, kd) * hold


def margins(transfer: Transfer, kp, ki=0.0, kd=0.0, omega=None, sample_delay=0.0):
    """``(gain_margin, phase_margin_deg, omega_pc, omega_gc)`` of :func:`loop_response` (module
    docstring): the smallest ``1/|L|`` where ``L`` crosses the negative real axis, and the
    smallest phase distance from −180° where ``|L|`` crosses 1, wrapped to [−180°, 180°)
    (negative: a loop past −180° at its gain crossing); ``inf``/``nan`` where the curve does not
    cross. ``omega`` the search grid (default ``transfer.frequency_grid()``)."""
    w = transfer.frequency_grid() if omega is None else np.asarray(omega, float)

    def L(x):
        return loop_response(transfer, x, kp, ki, kd, sample_delay)

    values = L(w)
    gm, w_pc = gain_margin(L, w, values)
    mag = np.abs(values)
    pm, w_gc = np.inf, np.nan
    for i in np.flatnonzero((mag[:-1] - 1.0) * (mag[1:] - 1.0) <= 0):
        x = _refine(lambda x: abs(L(np.array([x]))[0]) - 1.0, w[i], w[i + 1])
        p = float(np.mod(np.degrees(np.angle(L(np.array([x]))[0])), 360.0) - 180.0)
        if p < pm:
            pm, w_gc = p, x
    return float(gm), float(pm), float(w_pc), float(w_gc)


def gain_margin(loop, omega, values=None):
    """``(gain_margin, omega_pc)`` of a loop transfer ``loop(omega) -> L(iω)`` (complex, arrays)
    sampled on the grid ``omega``: the smallest ``1 / |L|`` over every crossing of the negative
    real axis, each refined by bisection; ``(inf, nan)`` without one. ``values``: ``loop(omega)``
    if already computed."""
    L = loop(omega) if values is None else values
    gm, w_pc = np.inf, np.nan
    for i in np.flatnonzero((L.imag[:-1] * L.imag[1:] <= 0) & (L.real[:-1] < 0)):
        x = _refine(lambda x: loop(np.array([x]))[0].imag, omega[i], omega[i + 1])
        lx = loop(np.array([x]))[0]
        if lx.real < 0 and 1.0 / abs(lx) < gm:
            gm, w_pc = 1.0 / abs(lx), x
    return float(gm), float(w_pc)


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
