"""The figures of a run and of a scene's layout (:mod:`jaxbelt.plot.runs`), drawn from hand-made
tracer histories on the grids of two built-in scenes (no simulation): the drawn lines hold the
histories in mm (µm and mrad for a steering loop), the profile panel the tracers sorted along the
belt at the times asked, the contact lines and segment names where the grid puts them; the layout
of the two-roller machine (50 mm rollers 275 mm apart) has its rollers, path and tracer points at
hand-computed places."""

from types import SimpleNamespace

import matplotlib

matplotlib.use("Agg")

import matplotlib.figure  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import jaxbelt as jb  # noqa: E402
from jaxbelt.plot import plot_run, plot_scene, plot_steering, tracer_labels  # noqa: E402


@pytest.fixture(scope="module")
def two_roller():
    scene = jb.load_scene("two-roller-1d")
    return scene, jb.build_mesh(scene)


@pytest.fixture(scope="module")
def steered_mesh():
    return jb.build_mesh(jb.load_scene("three-roller-steered"))  # 2D, 18 rows, one steering loop


def _history(mesh, k, lateral=False, fields=False, steered=False, seed=0):
    rng = np.random.default_rng(seed)
    n = len(mesh.tracer_x)
    b = 2 * mesh.n_eta if lateral else 1
    return SimpleNamespace(
        t=np.arange(1, k + 1) * 0.01, tracer_u=1e-3 * rng.standard_normal((k, n)),
        tracer_v=1e-4 * rng.standard_normal((k, n)) if lateral else None,
        u=1e-3 * rng.standard_normal((k, len(mesh.x), b)) if fields else None,
        control_u=1e-3 * rng.standard_normal((k, 1)) if steered else None,
        sensor_v=1e-5 * rng.standard_normal((k, 1)) if steered else None)


def test_tracer_panel_holds_every_history_in_mm_with_its_label(two_roller):
    _, mesh = two_roller
    tr = _history(mesh, 10)
    fig = plot_run(tr, mesh, title="my run")
    top, profile = fig.axes
    lines = top.get_lines()
    assert len(lines) == 20 and top.get_title() == "my run"
    for k, line in enumerate(lines):
        np.testing.assert_array_equal(line.get_xdata(), tr.t)
        np.testing.assert_allclose(line.get_ydata(), tr.tracer_u[:, k] * 1e3, rtol=1e-15)
    assert [t.get_text() for t in top.get_legend().get_texts()] == tracer_labels(mesh)
    plt.close(fig)


def test_profile_panel_draws_the_tracers_along_the_belt_at_four_times_by_default(two_roller):
    _, mesh = two_roller
    tr = _history(mesh, 10)
    fig = plot_run(tr, mesh)
    profile = fig.axes[1]
    order = np.argsort(mesh.tracer_x)
    profiles = [line for line in profile.get_lines() if line.get_label().startswith("t = ")]
    assert [line.get_label() for line in profiles] == ["t = 0.01 s", "t = 0.04 s", "t = 0.07 s", "t = 0.1 s"]
    for line, i in zip(profiles, [0, 3, 6, 9]):  # linspace(0, 9, 4) rounded down
        np.testing.assert_allclose(line.get_xdata(), np.sort(mesh.tracer_x) * 1e3)
        np.testing.assert_allclose(line.get_ydata(), tr.tracer_u[i, order] * 1e3)
    # where the four segments begin: each arc's contact lines (0, 157.08, 432.08, 589.16 mm)
    marks = [line for line in profile.get_lines() if not line.get_label().startswith("t = ")]
    np.testing.assert_allclose([m.get_xdata()[0] for m in marks], [0.0, 50 * np.pi, 50 * np.pi + 275,
                                                                   100 * np.pi + 275], atol=1e-9)
    assert [m.get_linestyle() for m in marks] == ["--", ":", "--", ":"]  # arcs dashed, spans dotted
    top = profile.child_axes[0]
    assert [t.get_text() for t in top.get_xticklabels()] == ["drive", "span 1", "idle", "span 2"]
    np.testing.assert_allclose(top.get_xticks(), [25 * np.pi, 50 * np.pi + 137.5, 75 * np.pi + 275,
                                                  100 * np.pi + 412.5], atol=1e-9)
    plt.close(fig)


def test_profile_at_the_times_asked_and_a_time_outside_the_run_refused(two_roller):
    _, mesh = two_roller
    tr = _history(mesh, 10)
    fig = plot_run(tr, mesh, times=[0.031, 0.1])
    profiles = [line for line in fig.axes[1].get_lines() if line.get_label().startswith("t = ")]
    assert [line.get_label() for line in profiles] == ["t = 0.03 s", "t = 0.1 s"]
    plt.close(fig)
    with pytest.raises(ValueError, match=r"t = 0.5 s is outside the run \(recorded 0.01 … 0.1 s\)"):
        plot_run(tr, mesh, times=[0.5])
    plt.close("all")


def test_full_fields_draw_the_whole_grid_in_the_profile(two_roller):
    _, mesh = two_roller
    tr = _history(mesh, 5, fields=True)
    fig = plot_run(tr, mesh, times=[0.02])
    (line,) = [line for line in fig.axes[1].get_lines() if line.get_label() == "t = 0.02 s"]
    np.testing.assert_allclose(line.get_xdata(), np.asarray(mesh.x) * 1e3)
    np.testing.assert_allclose(line.get_ydata(), tr.u[1, :, 0] * 1e3)
    plt.close(fig)


def test_a_steered_2d_run_has_lateral_and_steering_panels(steered_mesh):
    mesh = steered_mesh
    tr = _history(mesh, 6, lateral=True, fields=True, steered=True)
    fig = plot_run(tr, mesh, times=[0.06])
    u_ax, v_ax, steer_ax, u_prof, v_prof, actuator_ax = fig.axes
    assert (u_prof.get_ylabel(), v_prof.get_ylabel()) == ("u (along) [mm]", "v (lateral) [mm]")
    for k, line in enumerate(v_ax.get_lines()):
        np.testing.assert_allclose(line.get_ydata(), tr.tracer_v[:, k] * 1e3)
    assert len(v_ax.get_lines()) == len(mesh.tracer_x) == 30
    np.testing.assert_allclose(steer_ax.get_lines()[0].get_ydata(), tr.sensor_v[:, 0] * 1e6)
    np.testing.assert_allclose(actuator_ax.get_lines()[0].get_ydata(), tr.control_u[:, 0] * 1e3)
    row = 2 * (mesh.n_eta // 2)  # u of grid row 9 of 18 and its v beside it
    np.testing.assert_allclose(u_prof.get_lines()[0].get_ydata(), tr.u[5, :, row] * 1e3)
    np.testing.assert_allclose(v_prof.get_lines()[0].get_ydata(), tr.u[5, :, row + 1] * 1e3)
    plt.close(fig)


def test_steering_panel_units_labels_and_axes():
    fig, ax = plt.subplots()
    t = np.array([0.0, 0.1, 0.2])
    sensor, angle = np.array([[1e-6, -2e-6], [3e-6, 0.0], [0.0, 5e-6]]), np.array([[1e-3, 0.0], [2e-3, -1e-3], [0, 0]])
    assert plot_steering(ax, t, sensor, angle, labels=["a", "b"]) is ax
    right = fig.axes[1]
    assert [line.get_label() for line in ax.get_lines()[:2]] == ["sensor a", "sensor b"]
    assert [line.get_label() for line in right.get_lines()] == ["actuator a", "actuator b"]
    for i in range(2):
        np.testing.assert_allclose(ax.get_lines()[i].get_ydata(), sensor[:, i] * 1e6)
        np.testing.assert_allclose(right.get_lines()[i].get_ydata(), angle[:, i] * 1e3)
        assert right.get_lines()[i].get_linestyle() == "--" and ax.get_lines()[i].get_color() == f"C{i}"
    assert ax.get_lines()[2].get_ydata() == [0, 0]  # the zero line
    plot_steering(ax, t, sensor[:, :1], angle[:, :1])
    assert ax.get_lines()[-2].get_label() == "sensor"  # unlabelled loops
    plt.close(fig)


def _layout(two_roller):
    scene, mesh = two_roller
    return plot_scene(scene, mesh)


def test_scene_layout_draws_the_rollers_and_the_title(two_roller):
    fig = _layout(two_roller)
    ax = fig.axes[0]
    circles = ax.patches
    assert [tuple(c.center) for c in circles] == [(0.0, 0.0), (275.0, 0.0)]
    assert [c.radius for c in circles] == [50.0, 50.0]
    assert [t.get_text() for t in ax.texts] == ["1: drive\n(drive)", "2: idle\n(idle)"]
    assert ax.get_title() == "two-roller-1d: belt path 864.2 mm"
    plt.close(fig)


def test_scene_layout_draws_the_path_and_the_tracers_where_they_lie(two_roller):
    fig = _layout(two_roller)
    ax = fig.axes[0]
    paths = [line for line in ax.get_lines() if line.get_linestyle() == "-" and len(line.get_xdata()) > 1]
    assert len(paths) == 4
    arcs = [np.stack([p.get_xdata(), p.get_ydata()], 1) for p in paths if len(p.get_xdata()) == 60]
    for arc, centre in zip(arcs, [(0.0, 0.0), (275.0, 0.0)]):
        np.testing.assert_allclose(np.linalg.norm(arc - centre, axis=1), 50.0, rtol=1e-12)
    spans = [np.stack([p.get_xdata(), p.get_ydata()], 1) for p in paths if len(p.get_xdata()) == 2]
    np.testing.assert_allclose(spans, [[[0, -50], [275, -50]], [[275, 50], [0, 50]]], atol=1e-9)
    points = np.array([[line.get_xdata()[0], line.get_ydata()[0]] for line in ax.get_lines()
                       if line.get_marker() == "x" and len(line.get_xdata())])
    f = np.array([0.1, 0.3, 0.5, 0.7, 0.9])  # five tracers per segment at 10 %, 30 %, … along it
    drive = 50 * np.stack([np.cos(np.pi / 2 + np.pi * f), np.sin(np.pi / 2 + np.pi * f)], 1)  # down the left side
    span1 = np.stack([275 * f, np.full(5, -50.0)], 1)
    idle = [275, 0] + 50 * np.stack([np.cos(-np.pi / 2 + np.pi * f), np.sin(-np.pi / 2 + np.pi * f)], 1)
    span2 = np.stack([275 * (1 - f), np.full(5, 50.0)], 1)
    np.testing.assert_allclose(points, np.concatenate([drive, span1, idle, span2]), atol=1e-9)
    plt.close(fig)


def test_figures_are_written_and_closed_when_a_path_is_given(two_roller, tmp_path, monkeypatch):
    scene, mesh = two_roller
    written = []
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", lambda fig, path, **kw: written.append((fig, path)))
    assert plot_scene(scene, mesh, tmp_path / "scene.png") == tmp_path / "scene.png"
    assert plot_run(_history(mesh, 3), mesh, tmp_path / "run.png") == tmp_path / "run.png"
    assert [path for _, path in written] == [tmp_path / "scene.png", tmp_path / "run.png"]
    assert written[0][0].axes[0].get_title().startswith("two-roller-1d: belt path")
    assert plt.get_fignums() == []
