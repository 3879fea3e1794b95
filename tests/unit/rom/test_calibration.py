"""Calibration of the error estimate and the snapshot rule (:mod:`jaxbelt.rom.calibration`): the
safety factor ``margin / min(1, min η)`` on hand-picked effectivities; :func:`calibrate`'s
bookkeeping (true RMSE in µm, effectivity, error-free cases ignored) with the estimator replaced by
a known value; and :func:`snapshot_count` on a coarse idle-translated 1D belt with an oracle and a
useless predictor: it stops at the first chunk the oracle predicts, never for the useless one, and
its chunked snapshots equal one uninterrupted run's."""

import types

import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt.rom import calibration
from jaxbelt.rom.calibration import SAFETY_MARGIN, calibrate, safety_factor, snapshot_count
from jaxbelt.rom.snapshots import collect_first_order, tracer_operator
from helpers import load, scene_with


@pytest.mark.parametrize("eta,margin,factor", [
    ([0.8, 2.0, 1.1], SAFETY_MARGIN, SAFETY_MARGIN / 0.8), (0.25, 2.0, 8.0), ([], 1.5, 1.5),
    ([0.0, -1.0, np.inf, 0.9], 1.5, 1.5 / 0.9), ([3.0], 1.2, 1.2)])
def test_safety_factor_scales_the_margin_by_the_worst_short_estimate(eta, margin, factor):
    assert safety_factor(eta, margin) == pytest.approx(factor, rel=1e-15)


def test_calibrate_measures_the_true_error_in_micrometres_and_ignores_error_free_cases(monkeypatch):
    estimates = iter([3.0, 1.0, 5.0])
    monkeypatch.setattr(calibration, "error_rom",
                        lambda *a, **k: types.SimpleNamespace(rmse_um=next(estimates)))
    truth = np.zeros((4, 2))
    traj = types.SimpleNamespace(basis=None, coords=None, z_true0=None)
    off_by = lambda e: truth + e  # noqa: E731  (a uniform error of e metres: RMSE e)
    cases = [(None, truth, off_by(2e-6), traj, None), (None, truth, truth, traj, None),
             (None, truth, off_by(4e-6), traj, None)]
    cal = calibrate(cases, 0.01)
    assert [c.true_um for c in cal.cases] == pytest.approx([2.0, 0.0, 4.0])
    assert [c.estimate_um for c in cal.cases] == [3.0, 1.0, 5.0]
    assert cal.cases[0].effectivity == pytest.approx(1.5) and np.isnan(cal.cases[1].effectivity)
    assert cal.cases[2].effectivity == pytest.approx(1.25)
    assert cal.safety_factor == pytest.approx(SAFETY_MARGIN)  # every effectivity ≥ 1: the margin alone


@pytest.fixture(scope="module")
def machine():
    model, options = load(scene_with(lambda d: d["mesh"].update(roller_elements=[5, 5], free_elements=[6, 6]),
                                     "two-roller-1d-idle-translated"))
    return model, options.replace(n_steps=12)


@pytest.fixture(scope="module")
def whole_run(machine):
    model, options = machine
    return collect_first_order(model, options)[2]  # (2N, 13), the start state first


def test_chunked_snapshots_equal_one_run_and_a_useless_predictor_never_stops(machine, whole_run):
    model, options = machine
    C = tracer_operator(model)
    N = model.n_unknowns
    seen = []

    def zeros(Z, n):
        seen.append((Z.shape[1], n))
        return jnp.zeros((n, C.shape[0]))

    res = snapshot_count(model, zeros, options, tol_um=20.0, chunk=3, min_chunks=2)
    assert not res.converged and res.n_steps == 12 and res.Z.shape == whole_run.shape
    np.testing.assert_allclose(np.asarray(res.Z), np.asarray(whole_run), rtol=1e-9, atol=1e-15)
    assert seen == [(7, 3), (10, 3)]  # chunks 3 and 4, each predicted from the snapshots before it
    assert [m for m, _ in res.history] == [6, 9]
    for (m, err) in res.history:  # a zero prediction's error is the RMS of the chunk's tracers
        tracers = np.asarray(C @ whole_run[:N, m + 1:m + 4])
        assert err == pytest.approx(np.sqrt(np.mean(tracers ** 2)) * 1e6, rel=1e-9) and err > 0


def test_an_oracle_predictor_stops_the_rule_at_the_first_check(machine, whole_run):
    model, options = machine
    C = tracer_operator(model)
    N = model.n_unknowns

    def oracle(Z, n):
        m = Z.shape[1] - 1
        return (C @ whole_run[:N, m + 1:m + 1 + n]).T

    res = snapshot_count(model, oracle, options, chunk=3, min_chunks=2)
    assert res.converged and res.n_steps == 6 and res.Z.shape[1] == 7
    assert len(res.history) == 1 and res.history[0][0] == 6 and res.history[0][1] < 1e-6
