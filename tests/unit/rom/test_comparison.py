"""The reduction report (:mod:`jaxbelt.rom.comparison`) built by hand: the derived quantities
(steps predicted, effectivity = estimated / true RMSE) against hand values, and its JSON form
(method by name, arrays as lists, non-finite values ``null``, nested estimate and costs as
objects) through a strict ``json`` round trip; the divergence errors are floating-point errors."""

import json

import numpy as np
import pytest

from jaxbelt import rom
from jaxbelt.rom.calibration import CalibrationCase
from jaxbelt.rom.comparison import (FullRunDivergedError, ReducedRunDivergedError, ReductionCost, ReductionEstimate,
                                    ReductionResult)
from jaxbelt.rom.error_estimate import EstimateCost
from jaxbelt.rom.reduced_model import Spectra


def _estimate(rmse_um=6.0):
    return ReductionEstimate(error_um=np.array([4.0, 8.0]), rmse_um=rmse_um, max_um=8.0, raw_rmse_um=4.0,
                             safety_factor=1.5,
                             calibration=(CalibrationCase(2.0, 3.0, 1.5), CalibrationCase(0.0, 1.0, float("nan"))),
                             subspace_dim=12, projected_spectral_radius=0.99,
                             cost=EstimateCost(full_steps=10, jvps=30, windows=2, quasi_static_iterations=5,
                                               full_step_equivalents=40),
                             full_steps_predicted=80)


def _result(estimate=None, cost=None, **kw):
    fields = dict(method=rom.DMDc(modes=20), modes=20, modes_discarded=None, training_starts_at_step=None,
                  train_steps=40, n_train_runs=2, n_steps=100, predict_from_step=40, compared="tracer_u",
                  n_unknowns=139, n_tracers=20, rmse_um=4.0, rrmse=0.01, max_rmse_over_time_um=7.5,
                  t=np.array([0.1, 0.2]), error_um=np.array([3.0, np.inf]), estimate=estimate, cost=cost,
                  spectra=Spectra(singular_values=np.array([3.0, 1.0, 0.5]), marked=2))
    fields.update(kw)
    return ReductionResult(**fields)


def test_steps_predicted_are_those_after_the_prediction_start():
    assert _result().predict_steps == 60
    assert _result(predict_from_step=0).predict_steps == 100


def test_effectivity_is_the_estimated_over_the_true_error_where_there_is_an_estimate():
    assert _result().effectivity is None
    assert _result(estimate=_estimate(rmse_um=None)).effectivity is None
    assert _result(estimate=_estimate(6.0)).effectivity == pytest.approx(1.5)
    assert _result(rmse_um=0.0, estimate=_estimate(6.0)).effectivity is None  # no ratio to a zero error


def test_json_form_names_the_method_and_nests_the_estimate_and_the_costs():
    r = _result(estimate=_estimate(), cost=ReductionCost(offline_s=2.0, offline_first_call_s=5.0, online_s=0.01))
    d = json.loads(json.dumps(r.to_dict(), allow_nan=False))
    assert d["method"] == "dmdc" and d["modes"] == 20 and d["predict_steps"] == 60
    assert d["effectivity"] == pytest.approx(1.5)
    assert d["t"] == [0.1, 0.2] and d["error_um"] == [3.0, None]
    est = d["estimate"]
    assert est["error_um"] == [4.0, 8.0] and est["cost"]["full_step_equivalents"] == 40
    assert est["calibration"] == [{"true_um": 2.0, "estimate_um": 3.0, "effectivity": 1.5},
                                  {"true_um": 0.0, "estimate_um": 1.0, "effectivity": None}]
    assert d["cost"] == {"offline_s": 2.0, "offline_first_call_s": 5.0, "online_s": 0.01, "estimate_s": None,
                         "calibration_s": None}
    assert d["spectra"] == {"singular_values": [3.0, 1.0, 0.5], "marked": 2, "eigs": None, "eig_weights": None}
    assert d["sizing"] is None and d["modes_discarded"] is None


def test_a_result_without_estimate_or_cost_serialises_them_as_null():
    d = _result().to_dict()
    assert d["estimate"] is None and d["cost"] is None and d["effectivity"] is None


def test_divergence_errors_are_floating_point_errors():
    """Callers catch a diverged run as ``FloatingPointError`` whichever side diverged."""
    assert issubclass(FullRunDivergedError, FloatingPointError) and issubclass(ReducedRunDivergedError,
                                                                                 FloatingPointError)
    assert not issubclass(FullRunDivergedError, ReducedRunDivergedError)
