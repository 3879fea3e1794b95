"""The one stability-margin computation of loop design (jaxbelt.steering.transfer) against
python-control on an integrating plant with lag and delay (the delay as a 10th-order Padé
approximant), with P and PI control and the sampled loop's hold delay."""

import control
import numpy as np
import pytest

from jaxbelt.steering.plant import SteeringPlant
from jaxbelt.steering.transfer import gain_margin, loop_response, margins, pid_response

PLANT = SteeringPlant(gain=-0.06, lag=0.3, delay=0.05)


def _reference(kp, ki, delay):
    s = control.tf("s")
    pade = control.tf(*control.pade(delay, 10))
    G = np.sign(PLANT.gain) * PLANT.gain * pade / (s * (1 + PLANT.lag * s))
    gm, pm, w_pc, w_gc = control.margin(G * (kp + ki / s))
    return gm, pm, w_pc, w_gc


@pytest.mark.parametrize("kp,ki,hold", [(5.0, 0.0, 0.0), (5.0, 1.0, 0.0), (8.0, 2.0, 0.01)])
def test_margins_equal_python_control(kp, ki, hold):
    gm, pm, w_pc, w_gc = margins(PLANT, kp, ki, sample_delay=hold)
    ref = _reference(kp, ki, PLANT.delay + hold)
    assert gm == pytest.approx(ref[0], rel=1e-4) and pm == pytest.approx(ref[1], abs=0.01)
    assert w_pc == pytest.approx(ref[2], rel=1e-4) and w_gc == pytest.approx(ref[3], rel=1e-4)


def test_the_loop_is_sign_plant_controller_and_hold():
    w = np.geomspace(0.1, 100, 7)
    L = loop_response(PLANT, w, 2.0, 0.5, 0.1, sample_delay=0.02)
    expected = -PLANT.frequency_response(w) * (2.0 + 0.5 / (1j * w) + 0.1j * w) * np.exp(-0.02j * w)
    np.testing.assert_allclose(L, expected, rtol=1e-14)
    np.testing.assert_allclose(pid_response(w, 2.0, 0.5, 0.1), 2.0 + 0.5 / (1j * w) + 0.1j * w, rtol=1e-15)


def test_a_loop_that_never_crosses_has_no_gain_margin():
    w = np.geomspace(0.1, 10, 50)
    gm, w_pc = gain_margin(lambda x: 1.0 / (1j * x + 1.0), w)  # a first-order lag: phase above −90°
    assert gm == np.inf and np.isnan(w_pc)
