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

**The loop's recirculation.** A belt is a closed loop: the lateral position the rollers carry
(no slip) comes round again after one transit ``L_loop / V``, so the steady walk is built lap by
lap, a smoothed staircase, not a ramp — and the phase of the plant falls by ``2π`` per
``2π V / L_loop`` of frequency. A P loop goes unstable near the transit frequency, far below what
the form above predicts. The full form (every extra field zero gives the one above):

    G(s) = e^{−θ s} [ D + k (1 + z s) / ((1 + τ s)(1 + τ₂ s)) · Q(s) ],
    Q(s) = T_r / (1 − R(s)),  R(s) = e^{−θ_r s} / (1 + τ_r s)²,  T_r = θ_r + 2 τ_r

(``Q = 1/s`` without recirculation). ``R`` is one lap (a transport delay and the smoothing of the
spans), ``Q → 1/s`` for ``s → 0`` so ``k`` stays the steady coefficient, ``D`` the sensor's direct
(elastic) response to the roller's angle, ``(1 + z s)/((1 + τ s)(1 + τ₂ s))`` the first lap's
shape. In the string limit the structure is exact with two spans (:func:`jaxbelt.lateral_theory.string_loop_response`;
``docs/steering.md``).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np


@dataclasses.dataclass(frozen=True)
class SteeringPlant:
    """``G(s)`` of the module docstring.

    **Fields:** ``gain`` ``k``, m/s per rad (signed; the steady walk per actuator angle); ``lag``
    ``τ``, s; ``delay`` ``θ``, s; ``lag2`` ``τ₂``, s; ``zero`` ``z``, s; ``feedthrough`` ``D``, m per
    rad (the sensor's direct response); ``loop_delay`` ``θ_r``, s, and ``loop_lag`` ``τ_r``, s, the
    recirculation (both 0: none, ``Q = 1/s``)."""

    gain: float
    lag: float
    delay: float
    lag2: float = 0.0
    zero: float = 0.0
    feedthrough: float = 0.0
    loop_delay: float = 0.0
    loop_lag: float = 0.0

    @property
    def recirculating(self) -> bool:
        return self.loop_delay > 0 or self.loop_lag > 0

    @property
    def loop_time(self) -> float:
        """``T_r = θ_r + 2 τ_r``, s: one lap of the recirculation (0 without)."""
        return self.loop_delay + 2 * self.loop_lag

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    def frequency_response(self, omega):
        """``G(iω)`` for angular frequencies ``omega`` (rad/s), complex."""
        s = 1j * np.asarray(omega, float)
        shape = (1.0 + self.zero * s) / ((1.0 + self.lag * s) * (1.0 + self.lag2 * s))
        if self.recirculating:
            q = self.loop_time / (1.0 - np.exp(-self.loop_delay * s) / (1.0 + self.loop_lag * s) ** 2)
        else:
            q = 1.0 / s
        return np.exp(-self.delay * s) * (self.feedthrough + self.gain * shape * q)

    def step_response(self, t, amplitude: float = 1.0):
        """Sensor displacement (m) at times ``t`` (s) after a step of ``amplitude`` rad at ``t = 0``.
        The plain form in closed form, ``k a (t' − τ (1 − e^{−t'/τ}))``, ``t' = max(t − θ, 0)``;
        the full form by time stepping (:func:`plant_step_response`)."""
        t = np.asarray(t, float)
        if self.recirculating or self.lag2 or self.zero or self.feedthrough:
            return amplitude * np.asarray(plant_step_response(plant_parameters(self), jnp.asarray(t), _grid_step(self, t)))
        tp = np.maximum(t - self.delay, 0.0)
        lagged = self.lag * -np.expm1(-tp / self.lag) if self.lag > 0 else 0.0 * tp
        return self.gain * amplitude * (tp - lagged)

    def loop_response(self, omega, kp, ki=0.0, kd=0.0, sample_delay=0.0):
        """The loop transfer ``L(iω) = |G(iω)| … C(iω)`` with the loop's sign folded in (complex),
        times ``e^{−iω d}`` for the sampled loop's own delay ``d = sample_delay`` s (the zero-order
        hold's ``T_s / 2``: :func:`jaxbelt.design.steering.sampling_delay`)."""
        s = 1j * np.asarray(omega, float)
        hold = np.exp(-sample_delay * s) if sample_delay else 1.0
        return abs(self.gain) / self.gain * self.frequency_response(omega) * (kp + ki / s + kd * s) * hold

    def margins(self, kp, ki=0.0, kd=0.0, omega=None, sample_delay=0.0):
        """``(gain_margin, phase_margin_deg, omega_pc, omega_gc)`` of the loop with a PID
        controller (gains in SI: rad/m, rad/(m s), rad s/m) and the sampled loop's own delay
        ``sample_delay`` s (:meth:`loop_response`; 0: the continuous loop). Found on a log grid
        refined by bisection; ``inf`` where the curve does not cross. Each margin is the smallest
        over all its crossings (a recirculating plant crosses once per lap); the phase margin is
        wrapped to [−180°, 180°), negative for a loop past −180° at its gain crossing."""
        w = np.logspace(-4, 3, 20000) if omega is None else np.asarray(omega, float)
        L = self.loop_response(w, kp, ki, kd, sample_delay)
        mag = np.abs(L)
        gm, w_pc = gain_margin(lambda x: self.loop_response(x, kp, ki, kd, sample_delay), w, L)
        pm, w_gc = np.inf, np.nan
        # every gain crossing: the phase's distance from −180°, wrapped to [−180°, 180°) (negative:
        # the loop is past it); the smallest decides, as python-control's stability_margins
        for i in np.flatnonzero((mag[:-1] - 1.0) * (mag[1:] - 1.0) <= 0):
            x = _refine(lambda x: abs(self.loop_response(np.array([x]), kp, ki, kd, sample_delay)[0]) - 1.0,
                        w[i], w[i + 1])
            p = float(np.mod(np.degrees(np.angle(self.loop_response(np.array([x]), kp, ki, kd, sample_delay)[0])),
                             360.0) - 180.0)
            if p < pm:
                pm, w_gc = p, x
        return float(gm), float(pm), float(w_pc), float(w_gc)


def gain_margin(loop, omega, values=None):
    """``(gain_margin, omega_pc)`` of a loop transfer ``loop(omega) -> L(iω)`` (complex, arrays)
    sampled on the grid ``omega``: the smallest ``1 / |L|`` over every crossing of the negative
    real axis (a recirculating plant crosses once per lap), each refined by bisection;
    ``(inf, nan)`` without one. ``values``: ``loop(omega)`` if already computed."""
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


def plant_parameters(p: SteeringPlant):
    """The parameter vector ``(k, τ, τ₂, z, θ, D, θ_r, τ_r)`` of :func:`plant_step_response`."""
    return jnp.asarray([p.gain, p.lag, p.lag2, p.zero, p.delay, p.feedthrough, p.loop_delay, p.loop_lag], float)


def _grid_step(p: SteeringPlant, t) -> float:
    """The time step of :func:`plant_step_response`: 1/20 of the shortest time constant, at most
    1/200 of the span of ``t``, at least 1e-4 s."""
    scales = [x for x in (p.lag, p.lag2, p.loop_lag, p.loop_delay) if x > 0]
    h = min(scales + [float(np.max(t, initial=1.0))]) / 20
    return float(max(min(h, float(np.max(t, initial=1.0)) / 200), 1e-4))


def _tustin(b_num, a_den, h):
    """``(1 + b s)/(1 + a s)`` by Tustin: ``y_k = c y_{k−1} + d0 x_k + d1 x_{k−1}``."""
    den = h + 2 * a_den
    return (2 * a_den - h) / den, (h + 2 * b_num) / den, (h - 2 * b_num) / den


def plant_step_response(params, t, h: float):
    """Unit-step response of the full :class:`SteeringPlant` form at times ``t`` (s), ``jnp``
    (differentiable in ``params`` = ``(k, τ, τ₂, z, θ, D, θ_r, τ_r)``, the identification's
    Jacobians): Tustin steps of ``h`` for the first-order blocks, the lap delay ``θ_r ≥ h`` by
    linear interpolation in the history, the output delay ``θ`` by interpolation."""
    k, tau, tau2, z, theta, D, thr, taur = [params[i] for i in range(8)]
    t = jnp.asarray(t)
    n = int(np.ceil(float(np.max(np.asarray(t))) / h)) + 2
    recirc = (thr > 0) | (taur > 0)
    thr_c = jnp.maximum(thr, h)
    Tr = jnp.where(recirc, thr_c + 2 * taur, 1.0)
    cr = _tustin(0.0, taur, h)
    c1 = _tustin(z, tau, h)
    c2 = _tustin(0.0, tau2, h)

    def blk(c, y_prev, x, x_prev):
        return c[0] * y_prev + c[1] * x + c[2] * x_prev

    def body(carry, kk):
        buf, w_prev, r1, r2, d_prev, f1, f2, q_prev = carry
        pos = kk - thr_c / h  # w at t − θ_r
        i0 = jnp.floor(pos).astype(int)
        f = pos - i0
        wd = jnp.where(i0 >= 0, (1 - f) * buf[jnp.clip(i0, 0, n - 1)] + f * buf[jnp.clip(i0 + 1, 0, n - 1)], 0.0)
        r1n = blk(cr, r1, wd, d_prev)
        r2n = blk(cr, r2, r1n, r1)
        w_loop = 1.0 + r2n
        w_int = w_prev + h  # the integrator 1/s of a unit step: t
        w = jnp.where(recirc, w_loop, w_int)
        q = Tr * w
        f1n = blk(c1, f1, q, q_prev)
        f2n = blk(c2, f2, f1n, f1)
        buf = buf.at[kk].set(w)
        return (buf, w, r1n, r2n, wd, f1n, f2n, q), f2n

    z0 = jnp.zeros((), t.dtype)
    init = (jnp.zeros(n, t.dtype), z0, z0, z0, z0, z0, z0, z0)
    _, x = jax.lax.scan(body, init, jnp.arange(n))
    x = jnp.concatenate([jnp.zeros(1, t.dtype), x])  # x(0) = 0
    grid = jnp.arange(n + 1) * h
    y = k * jnp.interp(t - theta, grid, x, left=0.0) + D * (t >= theta)
    return y
