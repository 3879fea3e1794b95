"""The full model's measured open-loop response of a steering loop, read in the frequency
domain: ``G(iω)`` from the step response of the actuator angle (:class:`MeasuredResponse`), the
gain and phase margins of a loop sampled on a frequency grid (:func:`grid_margins`), and the
integrating-plus-delay plant fitted to the step response (:func:`fit_plant`, what the SIMC rule
is made for). :func:`jaxbelt.design.tuning.open_loop_response` measures the response; the tuning
constrains its margins."""

from __future__ import annotations

import dataclasses

import numpy as np

from .plant import SteeringPlant


@dataclasses.dataclass(frozen=True)
class MeasuredResponse:
    """The full model's open-loop response of the sensor to the actuator angle.

    **Fields:** ``t`` (n,) s, the record times; ``step`` (n,) m per rad, the sensor displacement
    after a unit step of the actuator angle at ``t = 0`` (the run with the step minus the run
    without, so the scene's own disturbance cancels); ``dt`` s; ``rate`` m/s per rad, the final
    walk rate (the integrator's gain, signed)."""

    t: np.ndarray
    step: np.ndarray
    dt: float
    rate: float

    def frequency_response(self, omega):
        """``G(iω)`` (complex): ``rate / (iω) + Σ_j (h_j − rate) e^{−iω t_j} Δt`` with ``h_j`` the
        step response's increments per Δt; exact for the sampled record where the response has
        settled to a steady walk before its end."""
        w = np.asarray(omega, float)
        h = np.diff(np.concatenate([[0.0], self.step])) / self.dt - self.rate
        tj = np.arange(h.size) * self.dt
        return self.rate / (1j * w) + np.exp(-1j * np.outer(w, tj)) @ h * self.dt

    def margins(self, kp, ki=0.0, kd=0.0, omega=None):
        """``(gain_margin, phase_margin_deg, omega_pc, omega_gc)`` of ``L = sign(rate) G C``: the
        smallest over every crossing (the response may cross more than once)."""
        w = frequency_grid(self.dt) if omega is None else np.asarray(omega, float)
        return grid_margins(w, np.sign(self.rate) * self.frequency_response(w) * pid_response(w, kp, ki, kd))


def frequency_grid(dt):
    """The frequencies a loop is sampled at for its margins: 3000 log-spaced from 1e-3 rad/s to
    the Nyquist frequency ``π / dt``."""
    return np.logspace(-3, np.log10(np.pi / dt), 3000)


def pid_response(w, kp, ki, kd):
    """``C(iω) = k_p + k_i / (iω) + k_d iω`` of the PID law at the frequencies ``w``."""
    s = 1j * w
    return kp + ki / s + kd * s


def grid_margins(omega, L):
    """``(gain_margin, phase_margin_deg, omega_pc, omega_gc)`` of a loop sampled at ``omega``:
    the smallest ``1/|L|`` where ``L`` crosses the negative real axis and the smallest
    ``180° − |arg L|`` where ``|L|`` crosses 1 (crossings linearly interpolated); ``inf``/``nan``
    where there is none."""
    L = np.asarray(L)
    gm, w_pc, pm, w_gc = np.inf, np.nan, np.inf, np.nan
    im = L.imag
    for i in np.flatnonzero(im[:-1] * im[1:] < 0):
        f = im[i] / (im[i] - im[i + 1])
        Lc = L[i] + f * (L[i + 1] - L[i])
        if Lc.real < 0 and 1 / abs(Lc) < gm:
            gm, w_pc = 1 / abs(Lc), omega[i] + f * (omega[i + 1] - omega[i])
    a = np.abs(L) - 1
    for i in np.flatnonzero(a[:-1] * a[1:] <= 0):
        f = a[i] / (a[i] - a[i + 1]) if a[i] != a[i + 1] else 0.0
        Lc = L[i] + f * (L[i + 1] - L[i])
        p = 180.0 - abs(np.degrees(np.angle(Lc)))
        if p < pm:
            pm, w_gc = p, omega[i] + f * (omega[i + 1] - omega[i])
    return float(gm), float(pm), float(w_pc), float(w_gc)


def fit_plant(response: MeasuredResponse) -> SteeringPlant:
    """The least-squares fit of ``k e^{−θs}/(s(1+τs))`` to a measured step response: ``θ`` on a
    0.01 s grid and ``τ`` on a 0.02 s grid (both 0–2 s), ``k`` linear."""
    t, y = response.t, response.step
    taus = np.arange(1, 100) * 0.02
    best = (np.inf, 0.0, 0.0, 0.0)
    for theta in np.arange(0.0, 2.0, 0.01):
        tp = np.maximum(t - theta, 0.0)
        B = np.vstack([tp, tp - taus[:, None] * -np.expm1(-tp / taus[:, None])])  # τ = 0, then taus
        by, bb = B @ y, np.einsum("ij,ij->i", B, B)
        r = y @ y - by**2 / np.where(bb > 0, bb, np.inf)
        i = int(np.argmin(r))
        if r[i] < best[0]:
            best = (r[i], by[i] / bb[i], 0.0 if i == 0 else taus[i - 1], theta)
    return SteeringPlant(gain=float(best[1]), lag=float(best[2]), delay=float(best[3]))
