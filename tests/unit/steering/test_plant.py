"""The identified plant's own responses (jaxbelt.steering.plant): the step response by time
stepping (the full form's path) against the closed form of the integrating plant with lag and
delay, and the frequency response against the Laplace transform of the step response."""

import numpy as np
import pytest

from jaxbelt.steering.plant import SteeringPlant


def test_time_stepped_step_response_equals_the_closed_form():
    """A zero of 1e-9 s routes the plant through the time-stepped path; it must reproduce
    ``k a (t' − τ (1 − e^{−t'/τ}))``, ``t' = max(t − θ, 0)``, of the plain form."""
    plain = SteeringPlant(gain=-0.06, lag=0.3, delay=0.05)
    stepped = SteeringPlant(gain=-0.06, lag=0.3, delay=0.05, zero=1e-9)
    t = np.linspace(0.0, 6.0, 601)
    exact = plain.step_response(t, amplitude=2e-4)
    tp = np.maximum(t - 0.05, 0.0)
    np.testing.assert_allclose(exact, -0.06 * 2e-4 * (tp - 0.3 * (1 - np.exp(-tp / 0.3))), rtol=1e-12, atol=0)
    np.testing.assert_allclose(stepped.step_response(t, amplitude=2e-4), exact, rtol=0,
                               atol=2e-3 * np.max(np.abs(exact)))


def test_frequency_response_is_the_step_responses_transform():
    """``G(iω) = iω ∫ y(t) e^{−iωt} dt`` for a unit step response ``y``, the integral over a
    record long enough that ``y`` is a steady ramp beyond it (the ramp's tail added in closed form)."""
    p = SteeringPlant(gain=0.08, lag=0.2, delay=0.03, lag2=0.05, zero=0.1, feedthrough=0.002)
    dt, T = 2e-4, 12.0
    t = np.arange(0.0, T + dt / 2, dt)
    y = p.step_response(t)
    for w in (0.7, 3.0, 11.0):
        e = np.exp(-1j * w * t)
        integral = np.sum(0.5 * (y[1:] * e[1:] + y[:-1] * e[:-1])) * dt
        # beyond T: y = y(T) + k (t − T), whose transform from T on is e^{−iωT} (y(T)/(iω) + k/(iω)²)
        tail = np.exp(-1j * w * T) * (y[-1] / (1j * w) + p.gain / (1j * w) ** 2)
        assert 1j * w * (integral + tail) == pytest.approx(p.frequency_response(np.array([w]))[0], rel=2e-3)
