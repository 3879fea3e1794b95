"""The figure functions' shared pieces (:mod:`jaxbelt.plot._common`): a figure written to a path is
closed and the path returned, without a path the open figure; a panel drawn on the axes given or
on a new figure of the size asked; a result read as its entries by name (a mapping as it is, a
design result's fields as JSON data with ``yield_`` under ``"yield"``), anything else refused."""

import dataclasses

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from jaxbelt.plot._common import axes_or_new, finish_figure, pyplot, result_record  # noqa: E402


def test_pyplot_is_matplotlibs():
    assert pyplot() is plt


def test_finish_figure_writes_and_closes_or_returns_the_open_figure(tmp_path):
    fig = plt.figure()
    assert finish_figure(fig, None) is fig and plt.fignum_exists(fig.number)
    path = tmp_path / "f.png"
    assert finish_figure(fig, path, dpi=50) == path
    assert not plt.fignum_exists(fig.number)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    w, h = fig.get_size_inches()
    assert matplotlib.image.imread(path).shape[:2] == (round(h * 50), round(w * 50))  # written at the dpi asked


def test_axes_or_new_keeps_the_axes_given_or_makes_one_panel():
    fig, ax = plt.subplots()
    assert axes_or_new(ax) == (None, ax)
    new_fig, new_ax = axes_or_new(None, figsize=(3, 2))
    assert new_fig is not fig and new_fig.axes == [new_ax]
    np.testing.assert_allclose(new_fig.get_size_inches(), [3, 2])
    assert tuple(axes_or_new(None)[0].get_size_inches()) == (6, 4.5)
    plt.close("all")


@dataclasses.dataclass(frozen=True)
class Interval:
    low_um: float
    high_um: float


@dataclasses.dataclass(frozen=True)
class Outcome:
    yield_: float
    ci95: tuple
    limit: Interval
    samples: np.ndarray
    worst_um: float


def test_a_design_result_reads_as_its_fields_in_json_form():
    res = Outcome(yield_=0.9, ci95=(0.85, 0.95), limit=Interval(-20.0, 20.0), samples=np.array([1.5, 2.5]),
                  worst_um=float("inf"))
    assert result_record(res) == {"yield": 0.9, "ci95": [0.85, 0.95], "limit": {"low_um": -20.0, "high_um": 20.0},
                                  "samples": [1.5, 2.5], "worst_um": None}


def test_a_mapping_is_read_as_it_is_and_anything_else_is_refused():
    d = {"yield": 0.5, "yield_": 0.4}
    assert result_record(d) is d
    for bad, name in (([0.9], "list"), (0.9, "float"), (None, "NoneType")):
        with pytest.raises(TypeError, match=rf"^expected a result of jaxbelt.design or a mapping, got {name}$"):
            result_record(bad)
