"""Field pictures (``jaxbelt.plot.plot_fields``, ``plot_belt_3d``), tracer labels, and
``jaxbelt simulate --plot-fields / --plot-3d``: the drawn data are the simulated fields."""

import json

import matplotlib

matplotlib.use("Agg")

import matplotlib.figure  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import jaxbelt as jb  # noqa: E402
from jaxbelt import plot  # noqa: E402
from jaxbelt.cli import main  # noqa: E402

from helpers import COARSE_2D_TWO_ROLLER  # noqa: E402

# a tiny 2D belt on the two-roller machine: 28 columns × 3 rows, 5 steps, the idle roller moved
# 0.5 mm along its axis and tilted, and two extra tracers off the centre line
SMALL_2D = COARSE_2D_TWO_ROLLER + """\
[time]
dt_s = 0.02
t_end_s = 0.1
[output]
tracers_per_segment = 5
tracers_mm = [[300.0, 20.0], [10.0, -12.5]]
[variant."idle"]
translation_mm = [0.0, 0.0, 0.5]
rotation_mrad = [2.0, 1.0, 0.0]
"""


@pytest.fixture(scope="module")
def run2d(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "small2d.toml"
    path.write_text(SMALL_2D)
    scene = jb.load_scene(path)
    mesh = jb.build_mesh(scene)
    model, opts = jb.build_model(scene, mesh), jb.RunOptions.from_scene(scene)
    fields = jb.SaveAt(opts.saveat.every, fields=True)  # what --plot-fields switches on
    state, traj = jb.simulate(model, **opts.replace(saveat=fields))
    return path, mesh, model, state, traj


@pytest.fixture(scope="module")
def run1d():
    scene = jb.load_scene("two-roller-1d")
    mesh = jb.build_mesh(scene)
    model, opts = jb.build_model(scene, mesh), jb.RunOptions.from_scene(scene)
    state, traj = jb.simulate(model, **opts.replace(n_steps=6, saveat=jb.SaveAt(opts.saveat.every, fields=True)))
    return mesh, model, state, traj


def _closed(a):
    return np.concatenate([a, a[..., :1]], axis=-1)


def test_plot_fields_2d_draws_the_simulated_fields(run2d):
    _, _, model, _, traj = run2d
    t, u = np.asarray(traj.t), np.asarray(traj.u)
    axes = plot.plot_fields(model, traj, times=[0.041, 0.1])  # 0.041 → the recorded 0.04
    assert axes.shape == (2, 2)
    rows = [1, 4]
    for r, k in enumerate(rows):
        for c, sl in enumerate((slice(0, None, 2), slice(1, None, 2))):  # u, v interleaved per row
            a = axes[r, c]
            drawn = np.asarray(a.collections[0].get_array()).reshape(model.n_eta, model.n_xi + 1)
            np.testing.assert_allclose(drawn, _closed(u[k][:, sl].T * 1e3), rtol=0, atol=1e-12)
            assert f"t = {t[k]:.4g} s" in a.get_title() and a.get_title().startswith("uv"[c])
    # the lateral field of the tilted, moved idle roller is not zero, so the test can fail
    assert np.max(np.abs(u[4][:, 1::2])) > 1e-4
    top = [tl.get_text() for tl in axes[0, 0].child_axes[0].get_xticklabels()]
    assert top == ["drive", "span 1", "idle", "span 2"]
    # the roller arcs are marked between their contact lines
    segs = plot.belt_segments(model)
    x, nr = np.asarray(model.x), np.asarray(model.node_roller)
    assert segs[2]["x0"] == x[nr == 1][0] and segs[2]["x1"] == x[nr == 1][-1]
    assert np.isclose(sum(s["x1"] - s["x0"] for s in segs), x[-1] + np.asarray(model.ell)[-1])
    plt.close(axes[0, 0].figure)


def test_plot_fields_1d_and_bad_input(run1d):
    _, model, _, traj = run1d
    fig, ax = plt.subplots(3, 1)
    axes = plot.plot_fields(model, traj, ax=ax)  # default: three times, the last included, u only
    assert axes.shape == (3, 1) and axes[0, 0] is ax[0]
    u = np.asarray(traj.u)
    for r, k in enumerate([0, 2, 5]):  # linspace(0, 5, 3) rounded
        drawn = np.asarray(axes[r, 0].collections[0].get_array()).reshape(2, model.n_xi + 1)
        np.testing.assert_allclose(drawn, np.repeat(_closed(u[k][:, 0])[None] * 1e3, 2, 0), atol=1e-12)
    assert np.max(np.abs(u[5])) > 1e-6
    with pytest.raises(ValueError, match="1D model"):
        plot.plot_fields(model, traj, components="v")
    with pytest.raises(ValueError, match=r"outside the run \(recorded 0.005 … 0.03 s\)"):
        plot.plot_fields(model, traj, times=[0.02, 0.5])
    with pytest.raises(ValueError, match="outside the run"):
        plot.plot_fields(model, traj, times=[float("nan")])
    with pytest.raises(ValueError, match="2 axes given for 3 time"):
        plot.plot_fields(model, traj, ax=ax[:2])
    with pytest.raises(ValueError, match="no full fields"):
        plot.plot_fields(model, _no_u(traj))
    with pytest.raises(ValueError, match="1D model"):
        plot.plot_belt_3d(model, u[-1], color_by="v")
    plt.close(fig)
    ax3 = plot.plot_belt_3d(model, u[-1], color_by="u")  # 1D: the belt is a line, one segment per element
    uc = np.append(u[-1][:, 0], u[-1][0, 0]) * 1e3
    np.testing.assert_allclose(np.asarray(ax3.collections[0].get_array()), 0.5 * (uc[:-1] + uc[1:]), atol=1e-12)
    plt.close(ax3.figure)


def _no_u(traj):
    import dataclasses

    return dataclasses.replace(traj, u=None)


def test_tracer_labels_and_legend(run1d, run2d, monkeypatch, tmp_path):
    mesh1, model1, _, traj1 = run1d
    labels = plot.tracer_labels(model1)
    assert labels[:6] == ["drive, 10 %", "drive, 30 %", "drive, 50 %", "drive, 70 %", "drive, 90 %", "span 1, 10 %"]
    assert labels[-1] == "span 2, 90 %" and plot.tracer_labels(mesh1) == labels
    _, mesh2, model2, _, traj2 = run2d
    lab2 = plot.tracer_labels(model2)
    # [300, 20] mm: the drive arc is π·50 = 157.1 mm, span 1 is 275 mm long → 52 % along span 1
    assert lab2[-2] == "span 1, 52 % / z = +20 mm" and lab2[-1] == "drive, 6 % / z = -12 mm"
    assert lab2 == plot.tracer_labels(mesh2)
    saved = []
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", lambda self, *a, **k: saved.append(self))
    plot.plot_run(traj2, mesh2, tmp_path / "run.png")
    legend = saved[0].axes[0].get_legend()
    assert [tx.get_text() for tx in legend.get_texts()] == lab2
    lines = saved[0].axes[0].get_lines()
    np.testing.assert_allclose(lines[-2].get_ydata(), np.asarray(traj2.tracer_u)[:, -2] * 1e3)
    with pytest.raises(ValueError, match="outside the run"):
        plot.plot_run(traj2, mesh2, tmp_path / "run.png", times=[3.0])


def test_belt_3d_geometry_and_colours(run2d):
    _, mesh, model, state, _ = run2d
    c0 = mesh.path.centers[0]
    np.testing.assert_allclose(plot.belt_geometry_3d(model)[3], mesh.path.centers - c0, atol=1e-12)
    P, tang, normal, centres = plot.belt_geometry_3d(model, mesh)
    nr = np.asarray(model.node_roller)
    on = nr >= 0
    r = np.linalg.norm(P[on, 0, :2] - centres[nr[on]], axis=1)
    np.testing.assert_allclose(r, np.asarray(model.node_radius)[on], rtol=1e-12)  # arc nodes on the rollers
    np.testing.assert_allclose(np.linalg.norm(tang, axis=1), 1.0)
    u = np.asarray(state.u)
    f = 50.0
    surf = plot.belt_surface_3d(model, u, chi=state.chi, mesh=mesh, exaggerate=f)
    np.testing.assert_allclose(surf["reference"], P)
    d = (surf["points"] - P) / f  # the displacement drawn: u along the tangent, v across, w normal
    np.testing.assert_allclose(np.einsum("nka,na->nk", d, tang), u[:, 0::2], atol=1e-15)
    np.testing.assert_allclose(d[..., 2], u[:, 1::2], atol=1e-15)
    assert np.max(np.abs(surf["w"][on])) > 1e-5 and np.max(np.abs(u[:, 1::2])) > 1e-4  # the moved idle roller
    ax = plot.plot_belt_3d(model, u, chi=state.chi, mesh=mesh, exaggerate=f)
    coll = ax.collections[0]
    mag = np.hypot(u[:, 0::2], u[:, 1::2]) * 1e3  # (n_xi, n_eta), mm
    mc = np.concatenate([mag, mag[:1]])
    expect = 0.25 * (mc[:-1, :-1] + mc[1:, :-1] + mc[1:, 1:] + mc[:-1, 1:]).reshape(-1)
    np.testing.assert_allclose(np.asarray(coll.get_array()), expect, atol=1e-12)
    assert "displacements × 50" in ax.get_title()
    plt.close(ax.figure)
    with pytest.raises(ValueError, match="exaggerate"):
        plot.plot_belt_3d(model, u, exaggerate=-1)
    with pytest.raises(ValueError, match="shape"):
        plot.plot_belt_3d(model, u[None])


def test_cli_plot_fields_records_the_requested_times(run2d, tmp_path, capsys):
    path, _, model, _, traj = run2d
    png, png3, out = tmp_path / "fields.png", tmp_path / "belt.png", tmp_path / "run.npz"
    rc = main(["simulate", str(path), "--plot-fields", str(png), "--field-times", "0.04,0.1", "--plot-3d", str(png3),
               "--exaggerate", "40", "--out", str(out), "--json"])
    assert rc == 0
    s = json.loads(capsys.readouterr().out)
    assert s["field_times_s"] == [0.04, 0.1] and s["plot_fields"] == str(png) and s["plot_3d"] == str(png3)
    assert png.stat().st_size > 20_000 and png3.stat().st_size > 20_000
    data = np.load(out)
    assert "u" not in data  # the scene asks for tracers only: fields kept at the plotted times alone
    np.testing.assert_allclose(data["field_t"], [0.04, 0.1])
    np.testing.assert_allclose(data["field_u"], np.asarray(traj.u)[[1, 4]], rtol=0, atol=1e-12)
    np.testing.assert_allclose(data["tracer_u"], np.asarray(traj.tracer_u), rtol=0, atol=1e-12)


@pytest.mark.parametrize("argv,fragment", [
    (["two-roller-1d", "--plot-fields", "F.png", "--field-components", "u,v"], "no lateral displacement v"),
    (["two-roller-1d", "--t-end", "0.05", "--plot-fields", "F.png", "--field-times", "0.02,0.3"],
     "t = 0.3 s is outside the run (recorded 0.005 … 0.05 s)"),
    (["two-roller-1d", "--plot-fields", "F.png", "--field-times", "0.1,x"], "comma-separated"),
    (["two-roller-1d", "--field-times", "0.1"], "needs --plot-fields or --plot-3d"),
    (["two-roller-1d", "--plot-3d", "F.png", "--exaggerate", "-2"], "--exaggerate"),
])
def test_cli_field_options_bad_input(argv, fragment, capsys):
    assert main(["simulate", *argv]) == 2
    err = capsys.readouterr().err
    assert fragment in err and "Traceback" not in err


def test_figure_functions_keep_the_backend_and_return_figures(run2d, tmp_path):
    """The library never selects a backend (a notebook's inline backend survives a plot call), and
    every figure-level function returns its open figure when no path is given."""
    _, mesh2, _, _, traj2 = run2d
    before = matplotlib.get_backend()
    plt.switch_backend("svg")  # a backend other than Agg: a plot call must not switch it back
    try:
        fig = plot.plot_run(traj2, mesh2, times=[0.02, 0.1])
        assert isinstance(fig, matplotlib.figure.Figure) and matplotlib.get_backend() == "svg"
        np.testing.assert_allclose(fig.axes[0].get_lines()[0].get_ydata(), np.asarray(traj2.tracer_u)[:, 0] * 1e3)
        res = dict(yield_=0.9, ci95=[0.85, 0.95], samples=50, metric="lateral_drift", **{"yield": 0.9})
        fig2 = plot.plot_yield(np.linspace(0, 30, 50), 20.0, res)
        assert isinstance(fig2, matplotlib.figure.Figure) and matplotlib.get_backend() == "svg"
        assert fig2.axes[0].get_lines()[0].get_xdata()[0] == 20.0  # the limit line
        out = plot.plot_yield(np.linspace(0, 30, 50), 20.0, res, tmp_path / "y.png")
        assert out == tmp_path / "y.png" and out.stat().st_size > 0
        plt.close("all")
    finally:
        plt.switch_backend(before)


def test_run_plot_profiles_show_v_on_a_2d_belt(run2d):
    """On a 2D belt the profile along the belt is drawn for both components: u, and v across."""
    _, mesh2, _, _, traj2 = run2d
    fig = plot.plot_run(traj2, mesh2, times=[0.02, 0.1])
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert "u (along) [mm]" in labels and "v (lateral) [mm]" in labels
    v_ax = fig.axes[labels.index("v (lateral) [mm]")]
    i = int(np.argmin(np.abs(np.asarray(traj2.t) - 0.1)))  # the run keeps full fields: the centre row's v
    centre = 2 * (mesh2.n_eta // 2)
    np.testing.assert_allclose(v_ax.get_lines()[1].get_ydata(), np.asarray(traj2.u)[i, :, centre + 1] * 1e3)
    plt.close(fig)
