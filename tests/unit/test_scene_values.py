"""The checked readers of a scene table (:mod:`jaxbelt.scene_values`) on hand-made tables: each
accepted value comes back as given (vectors as float tuples), a missing optional key gives its
default, and every rejection is a :class:`SceneError` whose message names ``table.key``, the value
and the reason."""

import math
import re

import pytest

from jaxbelt.scene_values import SceneError, check_keys, choice, int_list, key_error, number, number_tuples, vector


def test_key_error_names_the_key_and_the_value_repr():
    e = key_error("belt.width_mm", "wide", "must be a number")
    assert isinstance(e, SceneError) and isinstance(e, ValueError)
    assert str(e) == "belt.width_mm = 'wide': must be a number"


def test_check_keys_accepts_allowed_keys_and_lists_them_sorted_on_an_unknown_one():
    check_keys({"a": 1, "b": 2}, {"a", "b", "c"}, "t")
    with pytest.raises(SceneError, match=r"^t\.colour = 'red': unknown key \(allowed: a, b, c\)$"):
        check_keys({"a": 1, "colour": "red"}, {"c", "a", "b"}, "t")


@pytest.mark.parametrize("value", [0, 3, -2.5, 1e300])
def test_number_returns_a_finite_number_unchanged(value):
    assert number({"k": value}, "k", "t") == value and type(number({"k": value}, "k", "t")) is type(value)


@pytest.mark.parametrize("value,kw,why", [
    (True, {}, "must be a number"), ("1", {}, "must be a number"), ([1.0], {}, "must be a number"),
    (2.0, {"integer": True}, "must be an integer"), (math.nan, {}, r"must be finite \(no NaN or inf\)"),
    (-math.inf, {}, "must be finite"), (0.0, {"positive": True}, "must be positive"),
    (-1e-12, {"nonneg": True}, "must not be negative"), (4, {"lo": 5}, "must be >= 5"),
    (1.0, {"hi": 1.0}, "must be < 1.0")])
def test_number_rejects_with_the_reason(value, kw, why):
    with pytest.raises(SceneError, match=rf"^t\.k = {re.escape(repr(value))}: {why}"):
        number({"k": value}, "k", "t", **kw)


def test_number_bounds_are_inclusive_below_and_exclusive_above():
    assert number({"k": 5}, "k", "t", lo=5, hi=6) == 5
    assert number({"k": 0.0}, "k", "t", nonneg=True) == 0.0


def test_missing_number_is_an_error_unless_optional():
    with pytest.raises(SceneError, match=r"^t\.k = None: required key is missing$"):
        number({}, "k", "t")
    assert number({}, "k", "t", required=False, default=7) == 7
    assert number({}, "k", "t", required=False) is None


def test_vector_returns_floats_and_checks_length_type_and_finiteness():
    assert vector({"v": [1, 2.5, -3]}, "v", "t", 3) == (1.0, 2.5, -3.0)
    assert vector({}, "v", "t", 2, default=[0, 1]) == (0, 1)
    with pytest.raises(SceneError, match=r"t\.v = \[1, 2\]: must be a list of 3 numbers"):
        vector({"v": [1, 2]}, "v", "t", 3)
    with pytest.raises(SceneError, match="must be a list of numbers"):
        vector({"v": [1, True]}, "v", "t", 2)
    with pytest.raises(SceneError, match="must be finite"):
        vector({"v": [1.0, math.inf]}, "v", "t", 2)
    with pytest.raises(SceneError, match="required key is missing"):
        vector({}, "v", "t", 2)


def test_number_tuples_accepts_a_list_of_pairs_and_rejects_any_bad_entry():
    assert number_tuples({}, "p", "t", 2, "pairs") == []
    assert number_tuples({"p": [[1, 2.0], [3, 4]]}, "p", "t", 2, "pairs") == [[1, 2.0], [3, 4]]
    for bad in ([[1, 2, 3]], [[1, math.nan]], [[1, False]], [(1, 2)], "1,2"):
        with pytest.raises(SceneError, match=r"^t\.p = .*: must be a list of pairs of finite numbers$"):
            number_tuples({"p": bad}, "p", "t", 2, "pairs")


def test_choice_returns_the_value_or_the_default_and_lists_the_choices():
    assert choice({"c": "b"}, "c", "t", ("a", "b")) == "b"
    assert choice({}, "c", "t", ("a", "b"), default="a") == "a"
    with pytest.raises(SceneError, match=r"^t\.c = 'z': must be one of a, b$"):
        choice({"c": "z"}, "c", "t", ("a", "b"))
    with pytest.raises(SceneError, match=r"^t\.c = None: required key is missing \(one of a, b\)$"):
        choice({}, "c", "t", ("a", "b"))


def test_choice_among_booleans_rejects_another_value_with_a_scene_error():
    """``[solver] lateral_transport`` and ``tension_stiffening`` are read as a choice of ``(True, False)``:
    a string or a number is refused (``1 == True`` in Python, not in a scene file), named as TOML spells it."""
    for bad in ("yes", 1, 0.0):
        with pytest.raises(SceneError, match=r"t\.flag = .*: must be one of true, false"):
            choice({"flag": bad}, "flag", "t", (True, False), default=False)
    assert choice({"flag": True}, "flag", "t", (True, False), default=False) is True


def test_int_list_returns_a_tuple_and_names_the_per_roller_rule():
    assert int_list({}, "n", "t", 2) is None
    assert int_list({"n": [3, 4]}, "n", "t", 2) == (3, 4)
    for bad in ([3], [3, 4.0], [3, True], "3,4"):
        with pytest.raises(SceneError, match=r"must be a list of 2 integers \(one per roller\)"):
            int_list({"n": bad}, "n", "t", 2)
