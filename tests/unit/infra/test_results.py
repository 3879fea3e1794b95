"""The JSON convention of :mod:`jaxbelt.infra.results` against hand-built expectations: nested dataclasses
become objects, arrays and tuples lists, numpy and JAX scalars Python numbers of the same kind,
non-finite floats ``null``; the output survives a strict ``json.dumps`` / ``json.loads`` round trip."""

import dataclasses
import json
import math

import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt.infra.results import Result, in_metric_unit, json_fields, to_json, unit_field, unit_key


@dataclasses.dataclass(frozen=True)
class _Inner(Result):
    gap_um: float
    flags: tuple


@dataclasses.dataclass(frozen=True)
class _Outer(Result):
    name: str
    inner: _Inner
    table_um: np.ndarray
    by_roller: dict


def _outer():
    return _Outer(name="drive", inner=_Inner(gap_um=np.float32(1.5), flags=(np.bool_(True), False)),
                  table_um=np.arange(6.0).reshape(2, 3), by_roller={1: np.int64(3), "idle": float("nan")})


def test_nested_result_becomes_plain_json_objects_and_lists():
    expected = {"name": "drive", "inner": {"gap_um": 1.5, "flags": [True, False]},
                "table_um": [[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]], "by_roller": {"1": 3, "idle": None}}
    assert _outer().to_dict() == expected
    assert json.loads(json.dumps(_outer().to_dict(), allow_nan=False)) == expected


@pytest.mark.parametrize("value,expected,kind", [
    (np.float64(2.25), 2.25, float), (np.float32(0.5), 0.5, float), (np.int8(-3), -3, int),
    (np.uint16(7), 7, int), (np.bool_(False), False, bool), (True, True, bool), (3, 3, int),
    (jnp.float64(1.25), 1.25, float), (jnp.asarray(4), 4, int)])
def test_scalars_become_python_numbers_of_the_same_kind(value, expected, kind):
    out = to_json(value)
    assert out == expected and type(out) is kind


@pytest.mark.parametrize("value", [float("inf"), -math.inf, float("nan"), np.float64("nan"), np.float32("-inf")])
def test_non_finite_floats_become_null(value):
    assert to_json(value) is None


def test_arrays_of_any_kind_and_rank_become_nested_lists_with_non_finite_entries_null():
    assert to_json(jnp.asarray([[1.0, np.inf], [np.nan, -2.0]])) == [[1.0, None], [None, -2.0]]
    assert to_json(np.zeros((0, 3))) == []
    assert to_json(np.asarray(5.0)) == 5.0  # a 0-d array is its value
    assert to_json(np.asarray([True, False])) == [True, False]


def test_strings_none_and_dataclass_types_pass_through_unchanged():
    assert to_json("µm") == "µm" and to_json(None) is None
    assert to_json(_Inner) is _Inner  # the class itself is not an instance to serialise
    assert to_json(((1, 2), [np.float64(3.0)])) == [[1, 2], [3.0]]


@dataclasses.dataclass(frozen=True)
class _Run(Result):
    full_um: float = in_metric_unit()
    note: str = ""
    unit: str = unit_field()


@dataclasses.dataclass(frozen=True)
class _Box(Result):
    limit_um: float = in_metric_unit()
    gap_um: float = 0.0
    runs: tuple = ()
    unit: str = "µm"


@pytest.mark.parametrize("unit, suffix", [("µm", "um"), ("mrad", "mrad"), ("µm/s", "um_per_s")])
def test_metric_values_are_keyed_by_the_records_unit_and_a_nested_unit_is_left_to_its_keys(unit, suffix):
    box = _Box(limit_um=2.0, gap_um=1.0, runs=(_Run(1.5, "corner", unit),), unit=unit)
    # the metric-valued fields name the record's unit; a field that is always in µm keeps its name
    assert box.to_dict() == {f"limit_{suffix}": 2.0, "gap_um": 1.0, "runs": [{f"full_{suffix}": 1.5, "note": "corner"}],
                             "unit": unit}
    assert json_fields(box.runs[0]) == {f"full_{suffix}": 1.5, "note": "corner"}


def test_unit_key_renames_the_micrometre_part_only():
    assert unit_key("translation_um_per_mm", "mrad") == "translation_mrad_per_mm"
    assert unit_key("rss_3sigma_um", "µm/s") == "rss_3sigma_um_per_s"
    assert unit_key("max_true_error_um", "µm") == "max_true_error_um"
    with pytest.raises(ValueError, match="not a metric unit"):
        unit_key("limit_um", "mm")
    with pytest.raises(ValueError, match="named for µm"):
        unit_key("limit", "mrad")
