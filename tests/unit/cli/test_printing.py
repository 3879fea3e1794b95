"""The design commands print every value in its metric's unit: a steering-angle or walk-rate
metric is not reported in µm. The records are the JSON of the results, whose keys name the unit of
the metric values (``worst_case_mrad``: :func:`jaxbelt.infra.results.unit_key`)."""

from jaxbelt.cli import sensitivity, sweep, tolerance
from jaxbelt.infra.results import unit_key


def _box(metric, limits=()):
    unit = limits[0]["unit"] if limits else {"steering_max": "mrad"}.get(metric, "µm")
    k = lambda name: unit_key(name, unit)  # noqa: E731
    return {"unit": unit, "limits": list(limits), "operation": "window", "metric": metric, k("limit_um"): 0.5,
            "t_eval_s": 1.0, "window_s": [0.8, 1.0],
            "half_widths": [{"component": "roller 1 dx", "half_width": 0.1, "unit": "mm", "share": 1.0}],
            "unconstrained": [], k("worst_case_um"): 0.49, "verification": [{}], "verified": True, "iterations": 1,
            k("predicted_worst_um"): 0.5, "binding": ["roller 1 dx"], k("rss_um"): 0.3,
            "discretisation": {"grid_fine": {"n_xi": 8, "n_eta": 2, "dt": 0.01}, k("worst_case_fine_um"): 0.48,
                               k("worst_case_um"): 0.49, "half_width_relative_change": 0.01}}


def test_tolerance_prints_the_metrics_unit(capsys):
    tolerance._print(_box("steering_max"))
    out = capsys.readouterr().out
    assert "µm" not in out
    assert "verified worst case 0.49 mrad" in out and "RSS stack-up with σ = h/3: 0.3 mrad" in out


def test_tolerance_with_several_limits_prints_the_first_limits_unit(capsys):
    limits = [{"metric": "lateral_max", "limit": 20.0, "unit": "µm", "worst_case": 19.0, "ratio": 0.95,
               "predicted_worst": 19.5, "binds": True},
              {"metric": "steering_max", "limit": 3.0, "unit": "mrad", "worst_case": 1.0, "ratio": 0.33,
               "predicted_worst": 1.0, "binds": False}]
    r = _box("lateral_max", limits)
    r["operation"] = "steady"
    tolerance._print(r)
    out = capsys.readouterr().out
    assert "verified worst case 0.49 µm" in out and "steering_max      verified worst 1 mrad" in out


def test_sensitivity_prints_the_metrics_unit(capsys):
    r = {"metric": "walk_rate", "t_eval_s": 1.0, "value_um_per_s": 2.0, "forward_s": 1.0, "gradient_s": 2.0,
         "gradient": {"roller 1": {"translation_um_per_s_per_mm": [0.0, 1.0, 0.0],
                                   "rotation_um_per_s_per_mrad": [0.0, 2.0, 0.0]}},
         "at_kink": False, "structural_zero": [], "unit": "µm/s"}
    sensitivity._print(r)
    out = capsys.readouterr().out
    assert "walk_rate = 2 µm/s at t = 1 s" in out and "[µm/s/mm]" in out and "[µm/s/mrad]" in out


def test_sweep_prints_the_stack_up_in_the_metrics_unit(capsys):
    r = {"ci95": [0.9, 1.0], "metric": "steering_max", "limit_mrad": 0.5, "yield": 1.0, "passed": 10, "samples": 10,
         "form_beta": 3.0, "form_yield": 0.99, "rss_3sigma_mrad": 0.2, "full_runs": 10, "reduced_runs": 0,
         "wall_s": 1.0, "configs_per_s": 10.0, "unit": "mrad"}
    sweep._print(r)
    out = capsys.readouterr().out
    assert "steering_max ≤ 0.5 mrad" in out and "(3σ) 0.2 mrad" in out and "µm" not in out
