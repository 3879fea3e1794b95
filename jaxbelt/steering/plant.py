"""The steering plant as a low-order transfer function: what a loop designer works with.

The belt's lateral response at an edge sensor to the steering roller's angle is, in the string
limit (Shelton's first-order span model), an integrator — a steady angle walks the belt at a
steady rate, the *steering coefficient* — behind the span's first-order lag and the transport
delay from the steering roller to the sensor. jaxbelt identifies that form from the full
model's open-loop step response (:func:`identify_plant`; the form a SIMC rule is made for by
:func:`fit_plant`):

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
from jax import lax

from ..infra.results import Result


@dataclasses.dataclass(frozen=True)
class SteeringPlant(Result):
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

    @property
    def sign(self) -> float:
        """The loop's sign, ``sign(k)`` (:class:`~jaxbelt.steering.transfer.Transfer`)."""
        return float(np.sign(self.gain))

    def frequency_grid(self):
        """20000 log-spaced angular frequencies from 1e-4 to 1e3 rad/s."""
        return np.logspace(-4, 3, 20000)


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


# ------------------------------------------------------------------------------ identification


def identify_plant(t, response, gain, loop_time, starts=None, iterations: int = 40) -> tuple[SteeringPlant, float]:
    """Fit the full :class:`SteeringPlant` form to a unit step response.

    **Arguments:** ``t`` (n,) s, the times of ``response`` (n,) m per rad (the step is at
    ``t = 0``); ``gain`` the steady coefficient ``k`` (fixed: the measured slope); ``loop_time``
    the belt's transit time ``L_loop / V`` (the recirculation's initial guess).
    **Returns:** ``(plant, error)``, ``error`` the largest deviation from ``response`` over the
    run as a fraction of its range. Levenberg–Marquardt on ``(τ, τ₂, z, θ, D, θ_r, τ_r)`` with the
    Jacobian by ``jax.jacfwd`` of the time-stepped response, from a few starts; time constants
    are kept ≥ 0 and ``θ_r`` ≥ one grid step.
    """
    t = np.asarray(t, float)
    y = np.asarray(response, float)
    scale = float(np.ptp(y)) or 1.0
    h = float(min(t[1] - t[0], loop_time / 100)) / 2
    tj = jnp.asarray(t)

    def full(q):
        return jnp.concatenate([jnp.asarray([gain], float), q[:3], q[3:4], q[4:5], q[5:7]])

    def resid(q):  # q = (τ, τ₂, z, θ, D, θ_r, τ_r)
        return (plant_step_response(full(q), tj, h) - y) / scale

    lo = np.array([0.0, 0.0, -10 * loop_time, 0.0, -np.inf, h, 0.0])
    if starts is None:
        starts = [[0.2 * loop_time, 0.1 * loop_time, z, 0.0, 0.0, f * loop_time, 0.1 * loop_time]
                  for f in (0.7, 0.85) for z in (0.0, -0.5 * loop_time)]
    lo_j = jnp.asarray(lo)

    def levenberg_marquardt(q0):  # one start; the starts run side by side (vmap), the loop compiled
        q = jnp.maximum(q0, lo_j)

        def step(_, st):
            q, r, lam, done = st
            J = jax.jacfwd(resid)(q)
            A, g = J.T @ J, J.T @ r
            qn = jnp.maximum(q - jnp.linalg.solve(A + lam * jnp.diag(jnp.diag(A) + 1e-12), g), lo_j)
            rn = resid(qn)
            better = rn @ rn < r @ r  # false for a non-finite trial: rejected, λ grows
            small = (r @ r - rn @ rn) < 1e-12 * (r @ r)
            stop = done | (better & small) | (~better & (lam * 10 > 1e8))
            keep = done | ~better
            return (jnp.where(keep, q, qn), jnp.where(keep, r, rn),
                    jnp.where(done, lam, jnp.where(better, lam / 3, lam * 10)), stop)

        q, r, _, _ = lax.fori_loop(0, iterations, step, (q, resid(q), jnp.asarray(1e-3), jnp.asarray(False)))
        return q, r

    qs, rs = jax.jit(jax.vmap(levenberg_marquardt))(jnp.asarray(np.asarray(starts, float)))
    qs, rs = np.asarray(qs), np.asarray(rs)
    best = int(np.argmin(np.sum(rs**2, axis=1)))
    q, r = qs[best], rs[best]
    plant = SteeringPlant(gain=float(gain), lag=float(q[0]), delay=float(q[3]), lag2=float(q[1]), zero=float(q[2]),
                          feedthrough=float(q[4]), loop_delay=float(q[5]), loop_lag=float(q[6]))
    return plant, float(np.max(np.abs(r)))


def fit_plant(response) -> SteeringPlant:
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
