"""The JSON convention of :mod:`jaxbelt.infra.results` against hand-built expectations: nested dataclasses
become objects, arrays and tuples lists, numpy and JAX scalars Python numbers of the same kind,
non-finite floats ``null``; the output survives a strict ``json.dumps`` / ``json.loads`` round trip."""

import dataclasses
import json
import math

import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt.infra.results import Result, to_json


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
