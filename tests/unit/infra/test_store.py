"""The sweep store of :mod:`jaxbelt.infra.store` on small hand-made chunks: appended chunks read back
in order with their dims, units' variables and model codes; a rerun finds the stored count for the
same study and refuses another study naming the keys that differ, or a directory that is no store."""

import json

import numpy as np
import pytest

from jaxbelt.infra.store import MODEL_CODES, append_chunk, load_sweep, open_sweep

IDENTITY = {"scene": "two-roller-1d", "metric": "max_lateral", "limit": 50.0, "seed": 7, "t_eval": [0.5, 1.0]}
LABELS = ["drive.x", "idle.x"]


def _chunk(n, offset=0, n_tracers=3):
    theta = np.arange(offset, offset + 2 * n, dtype=float).reshape(n, 2)
    return theta, {"metric": theta.sum(axis=1), "lateral_um": np.outer(theta[:, 0], np.arange(1.0, n_tracers + 1)),
                   "longitudinal_um": -np.outer(theta[:, 1], np.ones(n_tracers))}


def test_missing_or_empty_directory_holds_no_configurations(tmp_path):
    assert open_sweep(tmp_path / "absent", IDENTITY) == 0
    (tmp_path / "empty").mkdir()
    assert open_sweep(tmp_path / "empty", IDENTITY) == 0


def test_directory_with_other_files_is_refused(tmp_path):
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(ValueError, match="exists and is not a sweep store"):
        open_sweep(tmp_path, IDENTITY)


def test_appended_chunks_read_back_in_order_with_their_codes_and_labels(tmp_path):
    path = tmp_path / "sweep"
    t1, o1 = _chunk(3)
    t2, o2 = _chunk(2, offset=100)
    append_chunk(path, IDENTITY, LABELS, t1, o1, "full")
    append_chunk(path, IDENTITY, LABELS, t2, o2, np.array([1, 0]))
    assert open_sweep(path, IDENTITY) == 5
    ds = load_sweep(path)
    assert dict(ds.sizes) == {"config": 5, "param": 2, "tracer": 3}
    np.testing.assert_array_equal(ds["theta"].values, np.vstack([t1, t2]))
    np.testing.assert_array_equal(ds["metric"].values, np.r_[o1["metric"], o2["metric"]])
    np.testing.assert_array_equal(ds["lateral_um"].values, np.vstack([o1["lateral_um"], o2["lateral_um"]]))
    np.testing.assert_array_equal(ds["longitudinal_um"].values,
                                  np.vstack([o1["longitudinal_um"], o2["longitudinal_um"]]))
    assert ds["model"].values.tolist() == [MODEL_CODES["full"]] * 3 + [MODEL_CODES["reduced"], MODEL_CODES["full"]]
    assert ds["model"].dtype == np.int8 and ds["model"].attrs["flag_meanings"] == "full reduced"
    assert json.loads(ds.attrs["param_labels"]) == LABELS and json.loads(ds.attrs["identity"]) == IDENTITY
    assert "steering_mrad" not in ds and "saturated" not in ds


def test_identity_is_compared_as_json_so_tuples_equal_lists(tmp_path):
    t, o = _chunk(2)
    append_chunk(tmp_path / "s", IDENTITY, LABELS, t, o, "reduced")
    assert open_sweep(tmp_path / "s", dict(IDENTITY, t_eval=(0.5, 1.0))) == 2


def test_another_study_is_refused_naming_the_keys_that_differ(tmp_path):
    t, o = _chunk(2)
    append_chunk(tmp_path / "s", IDENTITY, LABELS, t, o, "full")
    other = dict(IDENTITY, seed=8, limit=40.0)
    with pytest.raises(ValueError, match=r"holds another sweep \(differs in limit, seed\)"):
        open_sweep(tmp_path / "s", other)
    with pytest.raises(ValueError, match=r"differs in distribution"):
        open_sweep(tmp_path / "s", dict(IDENTITY, distribution="normal"))


def test_steered_outputs_are_stored_with_their_types(tmp_path):
    theta = np.zeros((2, 1))
    outputs = {"metric": [1.0, 2.0], "steering_mrad": [0.25, 3.0], "saturated": [0, 1]}
    append_chunk(tmp_path / "s", IDENTITY, ["drive.tilt"], theta, outputs, "full")
    ds = load_sweep(tmp_path / "s")
    assert ds["saturated"].dtype == bool and ds["saturated"].values.tolist() == [False, True]
    np.testing.assert_array_equal(ds["steering_mrad"].values, [0.25, 3.0])
    assert "lateral_um" not in ds and dict(ds.sizes) == {"config": 2, "param": 1}


def test_unknown_model_name_is_refused(tmp_path):
    t, o = _chunk(1)
    with pytest.raises(ValueError, match="model = 'surrogate': one of full, reduced"):
        append_chunk(tmp_path / "s", IDENTITY, LABELS, t, o, "surrogate")
