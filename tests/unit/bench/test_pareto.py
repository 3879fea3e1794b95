"""The speed/accuracy trade's pure pieces (:mod:`jaxbelt.bench.pareto`) on hand-made candidate rows:
the Pareto front by any error (ties and repeated points included), its Markdown table line by line,
the errors of a run against the truth, and the figure's three panels (the points drawn, memory in
MiB, the error floor, hollow markers for projected times, the front's step line and labels, the
design tolerance)."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.figure  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from jaxbelt.bench import pareto  # noqa: E402

ROWS = {
    "grid a": dict(family="grid", time_s=1.0, lateral_max_um=3.0, longitudinal_final_um=10.0, bytes=2 * 2**20),
    "grid b": dict(family="grid", time_s=4.0, lateral_max_um=0.5, longitudinal_final_um=2.0, bytes=8 * 2**20),
    "dt": dict(family="Δt", time_s=2.0, lateral_max_um=3.0, longitudinal_final_um=1.0, bytes=None),
    "naive": dict(family="integrator", time_s=50.0, lateral_max_um=0.0, longitudinal_final_um=0.5, bytes=2**20,
                  projected=True),
}


def test_front_by_the_lateral_error_fastest_first():
    front = pareto.front_rows(ROWS)
    assert [r["name"] for r in front] == ["grid a", "grid b", "naive"]  # dt: as accurate as grid a, slower
    assert front[0] == {"name": "grid a", **ROWS["grid a"]}


def test_front_by_another_error():
    front = pareto.front_rows(ROWS, error=lambda r: r["longitudinal_final_um"])
    assert [r["name"] for r in front] == ["grid a", "dt", "naive"]  # grid b: slower than dt and less accurate


def test_ties_in_time_keep_the_more_accurate_and_repeats_keep_one():
    rows = {"x": dict(time_s=1.0, lateral_max_um=2.0), "y": dict(time_s=1.0, lateral_max_um=1.0),
            "z": dict(time_s=1.0, lateral_max_um=1.0), "w": dict(time_s=0.5, lateral_max_um=5.0)}
    assert [r["name"] for r in pareto.front_rows(rows)] == ["w", "y"]


def test_front_table_line_by_line():
    md = pareto.table_markdown({"scene": "belt", "t_end_s": 4.0, "rows": ROWS})
    lines = md.splitlines()
    assert lines[0].startswith("The Pareto front (lateral error against run time) on `belt` over 4 s (truth 36 × 208")
    assert lines[1] == ""
    assert lines[2] == ("| candidate | run time (s, 2-core CPU) | memory (MiB) | lateral error (µm) "
                        "| longitudinal error at T (µm) |")
    assert lines[4:] == ["| grid a | 1 | 2.0 | 3 | 10 |", "| grid b | 4 | 8.0 | 0.5 | 2 |",
                         "| naive | 50 | 1.0 | 0 | 0.5 |"]
    assert md.endswith("|\n")
    no_memory = pareto.table_markdown({"scene": "s", "t_end_s": 1.0, "rows": {"dt": ROWS["dt"]}})
    assert no_memory.splitlines()[-1] == "| dt | 2 |  | 3 | 1 |"


def test_errors_of_a_run_against_the_truth():
    tu = np.array([[0.0, 1.0], [2.0, 3.0]]) * 1e-6
    tv = np.zeros((2, 2))
    u = tu + np.array([[5.0, 0.0], [0.0, -1.5]]) * 1e-6  # the largest difference early, 1.5 µm at the end
    v = tv + np.array([[0.0, -0.25], [0.125, 0.0]]) * 1e-6
    assert pareto._errors(u, v, (tu, tv)) == pytest.approx(
        {"lateral_max_um": 0.25, "longitudinal_final_um": 1.5, "longitudinal_max_um": 5.0}, rel=1e-9)


@pytest.fixture
def drawn(monkeypatch, tmp_path):
    """The figure :func:`pareto.plot` writes (closed, its artists kept for inspection)."""
    saved = []
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", lambda fig, path, **kw: saved.append((fig, path)))
    pareto.plot({"scene": "belt", "t_end_s": 4.0, "rows": ROWS}, tmp_path / "p.png")
    (fig, path), = saved
    assert path == tmp_path / "p.png" and plt.get_fignums() == []
    return fig


def _points(ax):
    """``(x, y, hollow)`` of every candidate's marker (a point without a line)."""
    return [(line.get_xdata()[0], line.get_ydata()[0], line.get_markerfacecolor() == "none")
            for line in ax.get_lines() if line.get_linestyle() == "None"]


def test_time_panel_draws_every_row_with_the_error_floor(drawn):
    ax = drawn.axes[0]
    assert (ax.get_xscale(), ax.get_yscale()) == ("log", "log")
    # rows in order; naive's zero error drawn at the 1e-4 µm floor, hollow: its time is projected
    assert _points(ax) == [(1.0, 3.0, False), (4.0, 0.5, False), (2.0, 3.0, False), (50.0, 1e-4, True)]
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["grid", "Δt", "integrator"]
    step = [line for line in ax.get_lines() if line.get_linestyle() == "--"][0]
    assert list(step.get_xdata()) == [1.0, 4.0, 50.0] and list(step.get_ydata()) == [3.0, 0.5, 1e-4]
    assert sorted(t.get_text() for t in ax.texts) == ["grid a", "grid b", "naive"]
    tolerance = [line for line in ax.get_lines() if list(line.get_ydata()) == [20.0, 20.0]]
    assert len(tolerance) == 1


def test_memory_panel_skips_rows_without_a_memory_figure(drawn):
    ax = drawn.axes[1]
    assert _points(ax) == [(2.0, 3.0, False), (8.0, 0.5, False), (1.0, 1e-4, True)]  # MiB; dt has none
    assert ax.get_xlabel() == "memory of the compiled run (MiB)"
    assert [t.get_text() for t in ax.texts] == ["naive"]  # the smallest and the most accurate: the whole front


def test_longitudinal_panel_and_the_title(drawn):
    ax = drawn.axes[2]
    assert [(x, y) for x, y, _ in _points(ax)] == [(1.0, 10.0), (4.0, 2.0), (2.0, 1.0), (50.0, 0.5)]
    assert sorted(t.get_text() for t in ax.texts) == ["dt", "grid a", "naive"]
    assert drawn.get_suptitle().startswith("belt, 4 s: error against cost (Pareto front dashed; red: the 20 µm")
