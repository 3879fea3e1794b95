"""The command line: counts, outputs, and clean errors.

The runs are whole numbers of the time loop's checkpoint chunks (56, 9, 6 steps), so that each
compiled run holds one copy of the step."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from jaxbelt.cli import main


def test_info_json_counts(capsys):
    assert main(["info", "two-roller-1d", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["n_unknowns"] == 224
    assert info["n_dynamic"] == 139 and info["n_algebraic"] == 85
    assert info["n_xi"] == 220 and info["n_eta"] == 1 and info["bandwidth"] == 1
    assert [r["dynamic_dofs"] for r in info["rollers"]] == [[], ["az"]]


def test_info_text(capsys):
    assert main(["info", "two-roller-1d-tension"]) == 0
    out = capsys.readouterr().out
    assert "dynamic DOFs ['dx', 'az']" in out and "N = 224" in out


def test_info_shows_the_steering_loops(capsys):
    assert main(["info", "three-roller-steered", "--json"]) == 0
    (loop,) = json.loads(capsys.readouterr().out)["control"]
    assert (loop["actuator"], loop["axis"], loop["sensor_mm"]) == ("roller 2", "y", [1430.0, 200.0])
    assert (loop["kp_mrad_per_mm"], loop["ki_mrad_per_mm_s"], loop["sample_s"]) == (2.0, 0.5, 0.04)
    assert loop["limit_mrad"] == pytest.approx(3.0) and loop["rate_limit_mrad_s"] == pytest.approx(5.0)
    assert main(["info", "three-roller-steered"]) == 0
    out = capsys.readouterr().out
    assert "steering loop: 'roller 2' tilted about y" in out and "range ±3 mrad" in out and "every 0.04 s" in out
    assert main(["info", "two-roller-1d", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["control"] == []


def test_scenes_lists_builtins(capsys):
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out
    assert "two-roller-1d " in out and "two-roller-1d-train1" in out


def test_simulate_writes_npz_plot_and_json(tmp_path, capsys):
    out, png = tmp_path / "run.npz", tmp_path / "run.png"
    rc = main(["simulate", "two-roller-1d-train2", "--t-end", "0.28", "--out", str(out), "--plot", str(png), "--json"])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["n_steps"] == 56 and summary["belt_mass_rel_drift"] < 1e-13
    data = np.load(out)
    assert data["t"].shape == (56,) and data["tracer_u"].shape == (56, 20)
    assert data["roller_state"].shape == (56, 2, 2) and data["belt_mass"].shape == (56,)
    np.testing.assert_allclose(data["t"][-1], 0.28)
    assert png.stat().st_size > 10_000


def test_simulate_integrator_and_dt_options(capsys):
    assert main(["simulate", "two-roller-1d", "--t-end", "0.018", "--dt", "0.002", "--integrator", "naive", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["n_steps"] == 9 and s["integrator"] == "naive"


@pytest.mark.parametrize("argv,fragment", [
    (["simulate", "two-roller-1d", "--dt", "0.01"], "CFL"),
    (["simulate", "no-such-scene"], "unknown scene"),
    (["simulate", "two-roller-1d", "--t-end", "-1"], "--t-end"),
    (["info", "/nonexistent/scene.toml"], "does not exist"),
    (["simulate", "two-roller-1d", "--out", "/nonexistent/dir/a.npz"], "'/nonexistent/dir' does not exist"),
    (["simulate", "two-roller-1d", "--plot", "run.xyz"], "--plot = 'run.xyz': '.xyz' is not a figure format"),
    (["simulate", "two-roller-1d", "--plot-3d", "/"], "--plot-3d = '/': is a folder"),
    (["plot-scene", "two-roller-1d", "--out", "/nonexistent/scene.png"], "does not exist"),
    (["demo", "--out", "/nonexistent/demo.npz"], "does not exist"),
    (["simulate", "two-roller-1d", "--plot-times", "0.05"], "--plot-times = '0.05': needs --plot"),
    (["simulate", "two-roller-1d", "--exaggerate", "5"], "--exaggerate = 5: needs --plot-3d"),
    (["simulate", "/"], "is a folder, not a scene file"),
])
def test_bad_input_exits_nonzero_with_message(argv, fragment, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert fragment in err and "Traceback" not in err


def test_bad_scene_file_no_traceback(tmp_path):
    from importlib import resources

    text = (resources.files("jaxbelt") / "scenes" / "two-roller-1d.toml").read_text()
    p = tmp_path / "bad.toml"
    p.write_text(text.replace("width_mm = 50.0", "width_mm = nan"))
    r = subprocess.run([sys.executable, "-m", "jaxbelt.cli", "info", str(p)], capture_output=True, text=True)
    assert r.returncode == 2
    assert "belt.width_mm" in r.stderr and "Traceback" not in r.stderr


def test_diverging_run_is_reported(capsys):
    # eq. 3.56 literally, on a 10 mm translation with 3.9 mm elements: the weights extrapolate
    rc = main(["simulate", "two-roller-1d-train1", "--t-end", "1", "--transport", "source"])
    out, err = capsys.readouterr()
    assert rc == 3, (out, err)
    assert "extrapolated by more than half an element" in err and "diverged" in err
    assert "simulated" not in out  # no figures of a run that is not a solution


def test_plot_scene_and_2d_simulate(tmp_path, capsys):
    png = tmp_path / "scene.png"
    assert main(["plot-scene", "four-roller-external", "--out", str(png)]) == 0
    assert png.stat().st_size > 10_000
    out = tmp_path / "run.npz"
    assert main(["simulate", "three-roller-t72", "--t-end", "0.12", "--solver", "reuse", "--out", str(out), "--json"]) == 0
    data = np.load(out)
    assert data["tracer_u"].shape == (6, 30) and data["tracer_v"].shape == (6, 30)
    assert data["roller_state"].shape == (6, 3, 6)


def test_output_file_names_what_is_written(tmp_path):
    from jaxbelt.cli._common import output_file

    assert output_file("--out", tmp_path / "run.txt", kind="npz") == str(tmp_path / "run.txt.npz")  # numpy's suffix
    assert output_file("--out", tmp_path / "run.npz", kind="npz") == str(tmp_path / "run.npz")
    assert output_file("--plot", tmp_path / "fig.PDF") == str(tmp_path / "fig.PDF")
    assert output_file("--plot", None) is None


def test_end_time_off_the_step_grid_is_noted(capsys):
    from jaxbelt.cli._common import scene_from_args

    scene = scene_from_args("two-roller-1d", t_end=0.0123, dt=0.005)
    assert scene.time.n_steps == 2
    assert "takes 2 steps and ends at 0.01 s" in capsys.readouterr().err
    scene_from_args("two-roller-1d", t_end=0.01, dt=0.005)
    assert capsys.readouterr().err == ""


def test_design_metric_defaults_to_longitudinal_on_a_1d_scene():
    from jaxbelt.cli import build_parser
    from jaxbelt.cli._design import load_design_model

    args = build_parser().parse_args(["sensitivity", "two-roller-1d"])
    load_design_model(args)
    assert args.metric == "longitudinal_rms"
    args = build_parser().parse_args(["tolerance", "two-roller-1d", "--metric", "longitudinal_rms"])
    load_design_model(args)
    assert args.metric == "longitudinal_rms"


def test_xla_flags_only_those_xla_defines_and_the_callers_win(monkeypatch):
    from jaxbelt.cli import CLI_XLA_FLAGS, add_xla_flags, xla_knows_flag

    assert xla_knows_flag("xla_backend_optimization_level")
    assert not xla_knows_flag("xla_no_such_flag_in_any_release")
    monkeypatch.setenv("XLA_FLAGS", "--xla_backend_optimization_level=2")
    added = add_xla_flags({"xla_backend_optimization_level": "0", "xla_no_such_flag_in_any_release": "1",
                           **CLI_XLA_FLAGS})
    assert "xla_backend_optimization_level" not in added and "xla_no_such_flag_in_any_release" not in added
    flags = os.environ["XLA_FLAGS"]
    assert flags.startswith("--xla_backend_optimization_level=2") and "no_such_flag" not in flags
