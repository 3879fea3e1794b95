"""The typed records of the design results and their JSON (:mod:`jaxbelt.infra.results`): every
nested record becomes an object whose keys carry their unit, a record that leaves its unset parts
out says so, and the per-roller tables keep their ``{roller: {...}}`` shape."""

import json

import numpy as np
import pytest

from jaxbelt.accuracy import Grid
from jaxbelt.design import (ComponentGradient, MetricLimit, ReducedModelUse, RollerMisalignment, SensitivityReport,
                            StructuralZero, SweepResult, ToleranceBox, VerificationRun)
from jaxbelt.design.records import SurrogateValidation, misalignment_per_roller, sensitivity_per_roller
from jaxbelt.design.tolerance import BoxDiscretisation, LimitCheck
from jaxbelt.misalignment import ParameterSpace


def _space():
    """Two rollers, three varied components: roller 1's dz, roller 2's ax and ay."""
    return ParameterSpace(roller_names=("roller 1", "roller 2"), entries=((0, "dz"), (1, "ax"), (1, "ay")),
                          chi_index=(2, 6, 7), structural=())


def _round_trip(record) -> dict:
    """``to_dict()`` through a JSON text and back."""
    return json.loads(json.dumps(record.to_dict()))


def test_per_roller_tables_carry_their_units_and_fill_the_fixed_components():
    space = _space()
    box = misalignment_per_roller(space, [0.004, 0.02, 0.03])
    assert list(box) == ["roller 1", "roller 2"]
    assert box["roller 1"] == RollerMisalignment((0.0, 0.0, 0.004), (0.0, 0.0, 0.0))
    assert box["roller 2"].rotation_mrad == (0.02, 0.03, 0.0)
    assert _round_trip(box["roller 2"]) == {"translation_mm": [0.0, 0.0, 0.0], "rotation_mrad": [0.02, 0.03, 0.0]}
    grad = sensitivity_per_roller(space, [1000.0, 5.0, -6.0])
    assert _round_trip(grad["roller 1"]) == {"translation_um_per_mm": [0.0, 0.0, 1000.0],
                                             "rotation_um_per_mrad": [0.0, 0.0, 0.0]}


def _box(names=None) -> ToleranceBox:
    space = _space()
    h = np.array([0.004, 0.02, 0.03])
    by_limit = {"lateral_max": 19.5, "steering_max": 0.5} if names else None
    runs = (VerificationRun("worst corner", misalignment_per_roller(space, h), 19.9, 19.6, by_limit),
            VerificationRun("random corner", misalignment_per_roller(space, -h), 12.0, 11.8, by_limit))
    limits = () if not names else (
        LimitCheck("lateral_max", 20.0, "µm", 19.9, 19.6, 0.98, True),
        LimitCheck("steering_max", 3.0, "mrad", 0.6, 0.5, 0.5 / 3, False))
    return ToleranceBox(metric="lateral_max", limit_um=20.0, t_eval_s=None, half_widths=h, units=["mm", "mrad", "mrad"],
                        labels=space.labels(), box=misalignment_per_roller(space, h), share=np.array([0.2, 0.5, 0.3]),
                        predicted_worst_um=19.9, worst_case_um=19.6, verified=True, binding=["roller 2:ay"],
                        unconstrained=[], verification=runs, iterations=1, rss_um=9.0,
                        jacobian_um=np.ones((2, 3)), response0_um=np.zeros(2), limits=limits,
                        binding_limit="lateral_max", limit_names=names)


def test_tolerance_box_json_keys():
    r = _round_trip(_box())
    assert set(r) == {"metric", "limit_um", "t_eval_s", "box", "worst_case_um", "predicted_worst_um", "verified",
                      "binding", "unconstrained", "verification", "iterations", "rss_um", "limits", "binding_limit",
                      "half_widths", "unit"}
    assert r["box"]["roller 2"] == {"translation_mm": [0.0, 0.0, 0.0], "rotation_mrad": [0.02, 0.03, 0.0]}
    row = r["verification"][0]
    assert set(row) == {"kind", "corner", "predicted_um", "full_um"}  # one limit: no full_by_limit
    assert row["corner"]["roller 1"]["translation_mm"] == [0.0, 0.0, 0.004]
    assert r["limits"] == [] and r["half_widths"][1] == {"component": "roller 2:ax", "half_width": 0.02,
                                                         "unit": "mrad", "share": 0.5}


def test_tolerance_box_with_several_limits_json_keys():
    box = _box((("lateral_max", 20.0), ("steering_max", 3.0)))
    r = _round_trip(box)
    assert r["verification"][0]["full_by_limit"] == {"lateral_max": 19.5, "steering_max": 0.5}
    assert r["limits"][1] == {"metric": "steering_max", "limit": 3.0, "unit": "mrad", "predicted_worst": 0.6,
                              "worst_case": 0.5, "ratio": 0.5 / 3, "binds": False}
    assert [x.metric for x in box.limits if x.binds] == ["lateral_max"]


def test_box_discretisation_grids_are_objects():
    bars = BoxDiscretisation(worst_case_um=19.6, worst_case_fine_um=19.8, floor_um=0.0, floor_fine_um=0.0,
                             half_width_relative_change=-0.01, half_width_uncertainty=np.array([1e-4, 2e-4]),
                             grid=Grid(40, 3, 0.02), grid_fine=Grid(80, 5, 0.01), runs=3)
    r = _round_trip(bars)
    assert r["grid"] == {"n_xi": 40, "n_eta": 3, "dt": 0.02} and r["grid_fine"]["n_xi"] == 80


def _validation(**extra) -> SurrogateValidation:
    return SurrogateValidation(
        method="response", description="response surface", validation_runs=17, training_runs=5, n_validation=12,
        seed=7919, training_widths=(0.3, 0.2), safety=10.0, rho_max=2.5, max_true_error_um=1e-3,
        median_true_error_um=1e-4, max_bound_um=1e-2, effectivity_min=float("inf"), effectivity_median=12.0,
        loo_effectivity_min=3.0, metric_range_um=(1.0, 30.0), training_s=1.0, fit_s=0.0, validation_s=2.0,
        offline_s=3.0, **extra)


def _sweep(rom, **extra) -> SweepResult:
    return SweepResult(metric="lateral_max", limit_um=20.0, samples=4, seed=0, yield_=0.75, ci95=[0.3, 0.95],
                       passed=3, full_runs=4 + rom.validation_runs, reduced_runs=0, rom=rom,
                       metric_values=np.array([1.0, 2.0, 25.0, 3.0]), wall_s=1.0, configs_per_s=4.0, **extra)


def test_sweep_json_rom_record_is_flat_and_leaves_out_what_is_unset():
    assert _round_trip(_sweep(ReducedModelUse(used=False)))["rom"] == {"used": False}
    assert _round_trip(_sweep(ReducedModelUse(used=False, reason="no loop")))["rom"] == {"used": False,
                                                                                          "reason": "no loop"}
    use = ReducedModelUse(used=True, validation=_validation(steps_kept=1))
    r = _round_trip(_sweep(use))
    assert r["rom"]["used"] and r["rom"]["steps_kept"] == 1 and "n_modes" not in r["rom"]
    assert r["rom"]["effectivity_min"] is None  # inf: JSON has none
    assert r["rom"]["metric_range_um"] == [1.0, 30.0] and r["full_runs"] == 4 + 17
    assert "metric_values" not in r and r["yield"] == 0.75


def test_sweep_json_design_point_and_limits():
    space = _space()
    res = _sweep(ReducedModelUse(used=False), design_point=misalignment_per_roller(space, [0.01, -0.02, 0.0]),
                 limits=(MetricLimit("lateral_max", 20.0, "µm"), MetricLimit("steering_max", 3.0, "mrad")))
    r = _round_trip(res)
    assert r["design_point"]["roller 2"] == {"translation_mm": [0.0, 0.0, 0.0], "rotation_mrad": [-0.02, 0.0, 0.0]}
    assert r["limits"] == [{"metric": "lateral_max", "limit": 20.0, "unit": "µm"},
                           {"metric": "steering_max", "limit": 3.0, "unit": "mrad"}]


def test_sensitivity_report_json_keys():
    space = _space()
    rep = SensitivityReport(
        metric="lateral_max", value_um=0.0, t_eval_s=0.24,
        parameters=(ComponentGradient("roller 1:dz", "mm", 1000.0), ComponentGradient("roller 2:ax", "mrad", 5.0)),
        gradient=sensitivity_per_roller(space, [1000.0, 5.0, 0.0]),
        structural_zero=(StructuralZero("roller 1:az", "no static effect"),), at_kink=True,
        forward_s=0.1, gradient_s=0.2, compile_s=1.0)
    r = _round_trip(rep)
    assert r["parameters"][0] == {"component": "roller 1:dz", "unit": "mm", "gradient": 1000.0}
    assert r["gradient"]["roller 2"]["rotation_um_per_mrad"] == [5.0, 0.0, 0.0]
    assert r["structural_zero"] == [{"component": "roller 1:az", "reason": "no static effect"}]


def test_a_metric_in_mrad_or_um_per_s_is_keyed_by_its_unit_never_as_um():
    """A ``steering_max`` box (mrad), a ``walk_rate`` sensitivity (µm/s), a steered sweep with its
    surrogate: every key of a metric value names the record's unit, nested records included."""
    space = _space()
    h = np.array([0.004, 0.02, 0.03])
    runs = (VerificationRun("worst corner", misalignment_per_roller(space, h), 1.9, 1.8, None, "mrad"),)
    box = ToleranceBox(metric="steering_max", limit_um=2.0, t_eval_s=None, half_widths=h, units=["mm", "mrad", "mrad"],
                       labels=space.labels(), box=misalignment_per_roller(space, h), share=np.array([0.2, 0.5, 0.3]),
                       predicted_worst_um=1.9, worst_case_um=1.8, verified=False, binding=[], unconstrained=[],
                       verification=runs, iterations=1, rss_um=1.0, jacobian_um=np.ones((2, 3)),
                       response0_um=np.zeros(2), binding_limit="steering_max", unit="mrad")
    rep = SensitivityReport(metric="walk_rate", value_um=3.0, t_eval_s=2.0, parameters=(),
                            gradient=sensitivity_per_roller(space, [1.0, 5.0, 0.0], "µm/s"), structural_zero=(),
                            at_kink=False, forward_s=0.1, gradient_s=0.2, compile_s=1.0, unit="µm/s")
    sweep = _sweep(ReducedModelUse(used=False, validation=_validation(unit="mrad")), rss_3sigma_um=1.2, unit="mrad")
    sweep = SweepResult(**{**{f: getattr(sweep, f) for f in sweep.__dataclass_fields__}, "metric": "steering_max"})
    bars = BoxDiscretisation(worst_case_um=1.8, worst_case_fine_um=1.81, floor_um=0.0, floor_fine_um=0.0,
                             half_width_relative_change=-0.01, half_width_uncertainty=np.array([1e-4]),
                             grid=None, grid_fine=None, runs=2, unit="mrad")
    b, s, y, d = _round_trip(box), _round_trip(rep), _round_trip(sweep), _round_trip(bars)
    assert {"limit_mrad", "worst_case_mrad", "predicted_worst_mrad", "rss_mrad"} <= set(b)
    assert set(b["verification"][0]) == {"kind", "corner", "predicted_mrad", "full_mrad"}
    assert s["value_um_per_s"] == 3.0 and s["gradient"]["roller 1"] == {
        "translation_um_per_s_per_mm": [0.0, 0.0, 1.0], "rotation_um_per_s_per_mrad": [0.0, 0.0, 0.0]}
    assert y["limit_mrad"] == 20.0 and y["rss_3sigma_mrad"] == 1.2 and y["rom"]["max_bound_mrad"] == 1e-2
    assert set(d) >= {"worst_case_mrad", "worst_case_fine_mrad", "floor_mrad", "floor_fine_mrad"}
    for r in (b, s, y, d):
        assert not [k for k in json.dumps(r).split('"') if k.endswith("_um") or "_um_per_m" in k]


def test_sweep_keeps_its_configurations_out_of_the_json():
    """The sweep keeps its samples for what reads them further (the yield's error bar); the JSON
    names the seed and the distribution that draw them instead."""
    thetas = np.arange(8.0).reshape(4, 2)
    sweep = _sweep(ReducedModelUse(used=False), configurations=thetas)
    assert sweep.configurations is thetas
    assert "configurations" not in _round_trip(sweep) and "configurations" not in sweep.to_dict(values=True)
    assert _round_trip(sweep) == _round_trip(_sweep(ReducedModelUse(used=False)))


def test_the_yield_error_bar_needs_the_sweeps_configurations():
    from jaxbelt.design.sweep import yield_discretisation

    with pytest.raises(ValueError, match="configurations"):
        yield_discretisation(_sweep(ReducedModelUse(used=False)), None, None, None)
