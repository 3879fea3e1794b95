"""The command modules' shared pieces (:mod:`jaxbelt.cli._common`): the command-line overrides of a
scene's time and solver, checked before anything runs; the output file an option will write, refused
with the option named where it cannot be written; the numeric option checks; the number formatting
and the JSON-or-text output; against hand-written values and the exact messages."""

import argparse
import json
import math

import numpy as np
import pytest

import jaxbelt as jb
from helpers import COARSE_1D_TWO_ROLLER
from jaxbelt.cli import SimulationError, UsageError, main
from jaxbelt.cli._common import (check_at_least, emit, finite_or_none, fmt, load_run, output_file, print_json, rebuild,
                                 scene_from_args)



def test_without_overrides_the_scene_is_the_loaded_one(capsys):
    assert scene_from_args("two-roller-1d") == jb.load_scene("two-roller-1d")
    assert capsys.readouterr().err == ""


def test_time_overrides_replace_the_time_table_and_keep_the_rest():
    scene = scene_from_args("two-roller-1d", t_end=0.2, dt=0.004)
    assert (scene.time.t_end, scene.time.dt, scene.time.n_steps) == (0.2, 0.004, 50)
    assert scene.time.start == "rest" and scene.rollers == jb.load_scene("two-roller-1d").rollers
    only_dt = scene_from_args("two-roller-1d", dt=0.0025)  # the scene's own 5 s end
    assert (only_dt.time.t_end, only_dt.time.dt, only_dt.time.n_steps) == (5.0, 0.0025, 2000)


@pytest.mark.parametrize("t_end,dt,message", [
    (-1, None, "--t-end = -1: must be a positive number"),
    (0.0, None, "--t-end = 0.0: must be a positive number"),
    (None, 0, "--dt = 0: must be a positive number"),
    (None, float("nan"), "--dt = nan: must be a positive number"),
    (float("inf"), None, "--t-end = inf: must be a positive number"),
    (0.004, 0.005, "--t-end = 0.004: shorter than one step (dt = 0.005)"),
    (None, 6.0, "--t-end = 5.0: shorter than one step (dt = 6.0)"),  # the scene's own end against the new step
])
def test_bad_time_overrides_are_usage_errors_naming_the_option(t_end, dt, message):
    with pytest.raises(UsageError) as e:
        scene_from_args("two-roller-1d", t_end=t_end, dt=dt)
    assert str(e.value) == message


def test_solver_overrides_replace_only_the_names_given():
    own = jb.load_scene("two-roller-1d").solver
    scene = scene_from_args("two-roller-1d", integrator="naive")
    assert (scene.solver.integrator, scene.solver.linear_solver, scene.solver.transport) == (
        "naive", own.linear_solver, own.transport)
    scene = scene_from_args("two-roller-1d", transport="source", linear_solver="reuse")
    assert (scene.solver.integrator, scene.solver.linear_solver, scene.solver.transport) == (
        own.integrator, "reuse", "source")


def test_load_run_and_rebuild_give_the_scene_its_grid_model_and_run_settings(tmp_path):
    path = tmp_path / "coarse.toml"
    path.write_text(COARSE_1D_TWO_ROLLER)
    scene, mesh, model, options = load_run(str(path), t_end=0.1, dt=0.02, linear_solver="reuse")
    assert len(mesh.ell) == model.n_xi == 22
    assert model.n_unknowns == 22 + 4  # one unknown a node, two DOFs per roller
    assert (options.dt, options.n_steps) == (0.02, 5)
    assert jb.integrators.solver_name(options.solver) == "direct/reuse"
    assert mesh.length == pytest.approx(2 * math.pi * 0.05 + 2 * 0.275, rel=1e-12)
    longer = scene.replace(time=scene.time.__class__(dt=0.01, t_end=0.3))
    scene2, mesh2, model2, options2 = rebuild(longer)
    assert scene2 is longer and model2.n_xi == len(mesh2.ell) == 22 and (options2.dt, options2.n_steps) == (0.01, 30)


def test_output_file_refuses_a_folder_or_an_empty_name(tmp_path):
    for path in (tmp_path, ""):
        with pytest.raises(UsageError) as e:
            output_file("--out", path)
        assert str(e.value) == f"--out = {str(path)!r}: is a folder; give a file name"


def test_output_file_refuses_a_missing_folder_naming_it(tmp_path):
    missing = tmp_path / "no" / "fig.png"
    with pytest.raises(UsageError) as e:
        output_file("--plot", missing)
    assert str(e.value) == f"--plot = {str(missing)!r}: the folder {str(missing.parent)!r} does not exist"


def test_output_file_accepts_the_figure_formats_matplotlib_writes(tmp_path):
    from matplotlib.backend_bases import FigureCanvasBase

    formats = FigureCanvasBase.get_supported_filetypes()
    assert {"png", "pdf", "svg"} <= set(formats)
    for suffix in ("png", "PDF", "svg"):
        assert output_file("--plot", tmp_path / f"f.{suffix}") == str(tmp_path / f"f.{suffix}")
    assert output_file("--plot", tmp_path / "figure") == str(tmp_path / "figure")  # no suffix: PNG
    with pytest.raises(UsageError) as e:
        output_file("--plot-3d", tmp_path / "f.docx")
    assert str(e.value) == (f"--plot-3d = {str(tmp_path / 'f.docx')!r}: '.docx' is not a figure format matplotlib "
                            f"writes ({', '.join(sorted(formats))})")


def test_an_archive_gains_the_suffix_numpy_appends(tmp_path):
    assert output_file("--out", tmp_path / "run", kind="npz") == str(tmp_path / "run.npz")
    assert output_file("--out", tmp_path / "run.docx", kind="npz") == str(tmp_path / "run.docx.npz")  # not a figure
    np.savez(tmp_path / "run", a=np.zeros(1))
    assert (tmp_path / "run.npz").exists()  # what numpy writes, as reported


def test_check_at_least():
    check_at_least("--rounds", None)
    check_at_least("--rounds", 1)
    check_at_least("--samples", 2, low=2)
    with pytest.raises(UsageError, match=r"^--rounds = 0: must be at least 1$"):
        check_at_least("--rounds", 0)
    with pytest.raises(UsageError, match=r"^--samples = 1: must be at least 2$"):
        check_at_least("--samples", 1, low=2)


def test_finite_or_none_and_fmt():
    assert finite_or_none(np.float32(2.5)) == 2.5 and type(finite_or_none(np.float32(2.5))) is float
    assert finite_or_none("3") == 3.0
    assert finite_or_none(float("nan")) is None and finite_or_none(-np.inf) is None
    assert fmt(None) == "nan" and fmt(None, " µm") == "nan"
    assert fmt(0.5, " µm") == "0.5 µm" and fmt(1234567.0) == "1.235e+06" and fmt(2.0 / 3.0, "s") == "0.6667s"


def test_emit_prints_json_with_the_flag_else_the_text(capsys):
    data = {"n": 3, "name": "belt", "rows": [1.5, None]}
    emit(argparse.Namespace(json=True), data, lambda d: print("text"))
    out = capsys.readouterr().out
    assert json.loads(out) == data and out == json.dumps(data, indent=2) + "\n"
    seen = []
    emit(argparse.Namespace(json=False), data, seen.append)
    assert seen == [data] and capsys.readouterr().out == ""
    print_json([1, 2])
    assert capsys.readouterr().out == "[\n  1,\n  2\n]\n"


@pytest.mark.parametrize("error,code", [(UsageError, 2), (SimulationError, 3)])
def test_the_command_line_turns_each_error_kind_into_its_exit_code(monkeypatch, capsys, error, code):
    from jaxbelt.cli import scenes

    def fail(args):
        raise error("what went wrong")

    monkeypatch.setattr(scenes, "run", fail)
    assert main(["scenes"]) == code
    assert capsys.readouterr().err.strip() == "jaxbelt: error: what went wrong"
