"""``jaxbelt info`` (:mod:`jaxbelt.cli.info`) against hand counts on a coarse two-roller belt (5
elements on each 50 mm arc, 6 on each 275 mm span, 863 mm long on an 864.16 mm path, the idle roller
0.5 mm out along x): unknowns, algebraic rows, element lengths, CFL number, pre-tension strain,
rollers and segments; the half-bandwidth of hand-made block patterns; a steering loop in the units
of its table; and what the program decides for a scene, in words."""

import argparse
import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

import jaxbelt as jb
from helpers import COARSE_1D_TWO_ROLLER, scene_with
from jaxbelt.cli import info
from jaxbelt.cli.info import automatic_choices, bandwidth, load_run, loop_info, model_info

# the coarse two-roller string, pre-tensioned (a belt shorter than its path) and its idle roller moved
COARSE = COARSE_1D_TWO_ROLLER + """\
[belt]
length_mm = 863.0
[variant."idle"]
translation_mm = [0.5, 0.0, 0.0]
"""
ARC_MM, SPAN_MM = math.pi * 50.0, 275.0
PATH_MM = 2 * ARC_MM + 2 * SPAN_MM


@pytest.fixture(scope="module")
def coarse_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "coarse.toml"
    path.write_text(COARSE)
    return str(path)


@pytest.fixture(scope="module")
def coarse_info(coarse_path):
    return model_info(*load_run(coarse_path))


def test_counts_of_the_coarse_belt(coarse_info):
    i = coarse_info
    assert (i["scene"], i["kind"], i["n_xi"], i["n_eta"], i["block_size"]) == ("coarse", "1d", 22, 1, 1)
    # one unknown per node and two DOFs (dx, az) per roller; algebraic: the 6 + 6 nodes on the arcs (contact
    # lines included) and the prescribed roller rows (the drive's dx and az, the idle roller's dx)
    assert (i["n_belt_dofs"], i["n_roller_dofs"], i["n_unknowns"]) == (22, 4, 26)
    assert (i["n_algebraic"], i["n_dynamic"], i["dynamic_roller_rows"]) == (15, 11, 1)
    assert i["bandwidth"] == 1  # a string: each node couples to its neighbours
    assert i["path_length_mm"] == pytest.approx(PATH_MM, rel=1e-12)
    assert i["element_length_mm"] == pytest.approx([ARC_MM / 5, SPAN_MM / 6], rel=1e-12)
    assert (i["dt_s"], i["t_end_s"], i["n_steps"]) == (0.01, 0.2, 20)
    assert i["cfl"] == pytest.approx(0.5 * 0.01 / (ARC_MM / 5 * 1e-3), rel=1e-12)
    assert i["pretension_strain"] == pytest.approx(PATH_MM / 863.0 - 1.0, rel=1e-12)
    assert (i["integrator"], i["linear_solver"], i["transport"]) == ("direct", "kept-interior", "shift")
    assert (i["n_tracers"], i["output_every"], i["full_fields"], i["control"]) == (20, 1, False, [])


def test_rollers_and_segments_of_the_coarse_belt(coarse_info):
    drive, idle = coarse_info["rollers"]
    assert (drive["name"], drive["role"], drive["side"], drive["speed_m_s"]) == ("drive", "drive", "internal", 0.5)
    assert (idle["name"], idle["role"], idle["speed_m_s"]) == ("idle", "idle", None)
    for r, centre in ((drive, [0.0, 0.0]), (idle, [275.0, 0.0])):
        assert r["center_mm"] == pytest.approx(centre) and r["radius_mm"] == pytest.approx(50.0)
        assert r["wrap_deg"] == pytest.approx(180.0) and r["arc_mm"] == pytest.approx(ARC_MM) and r["elements"] == 5
    assert drive["dynamic_dofs"] == [] and idle["dynamic_dofs"] == ["az"]
    assert drive["prescribed"] == {"dx": 0.0} and idle["prescribed"] == {"dx": pytest.approx(5e-4)}
    segs = coarse_info["segments"]
    assert [(s["kind"], s["name"], s["elements"]) for s in segs] == [
        ("roller", "drive", 5), ("free", "drive → idle", 6), ("roller", "idle", 5), ("free", "idle → drive", 6)]
    assert [s["length_mm"] for s in segs] == pytest.approx([ARC_MM, SPAN_MM, ARC_MM, SPAN_MM])


def test_the_text_output_states_the_counts(coarse_path, capsys):
    assert info.run(argparse.Namespace(scene=coarse_path, json=False)) == 0
    out = capsys.readouterr().out
    assert out.startswith("scene coarse (1d): Two equal rollers")
    assert "unknowns N = 26  (belt 22 + rollers 4); algebraic 15, dynamic 11 (= N after elimination)" in out
    assert ("grid n_xi × n_eta = 22 × 1, block size 1, bandwidth 1, path 864.159 mm, "
            "elements 31.416–45.833 mm") in out
    assert "time dt = 0.01 s, 20 steps to 0.2 s, CFL number 0.159" in out
    assert "pre-tension strain 0.00134" in out
    assert "roller 'idle': idle, internal, r = 50 mm at [275.0, 0.0], wrap 180.0° (5 elements), dynamic DOFs " \
           "['az'], prescribed {'dx': 0.0005}" in out
    assert ("roller 'drive': drive, internal, r = 50 mm at [0.0, 0.0], wrap 180.0° (5 elements), "
            "dynamic DOFs -\n") in out
    assert out.count("  automatic: ") == 2
    assert out.endswith("\n    free   idle → drive                275.000 mm     6 elements\n")


def _blocks(b, where):
    """Zero diagonal/upper/lower blocks (3 block rows of size ``b``) but for the entries ``where``:
    ``{"diag"|"upper"|"lower": [(block row, i, j), …]}``."""
    K = SimpleNamespace(block=b, **{k: np.zeros((3, b, b)) for k in ("diag", "upper", "lower")})
    for name, entries in where.items():
        for n, i, j in entries:
            getattr(K, name)[n, i, j] = 1.0
    return K


@pytest.mark.parametrize("where,expected", [
    ({}, 0),
    ({"diag": [(0, 0, 0), (2, 1, 1)]}, 0),
    ({"diag": [(1, 0, 1)]}, 1),
    ({"diag": [(1, 1, 0)]}, 1),
    ({"upper": [(0, 1, 0)]}, 1),  # row 1 of a block, column 0 of the next: 1 apart
    ({"upper": [(2, 0, 1)]}, 3),
    ({"lower": [(1, 0, 1)]}, 1),
    ({"lower": [(0, 1, 0)]}, 3),
    ({"diag": [(0, 0, 1)], "upper": [(0, 0, 1)], "lower": [(0, 1, 1)]}, 3),
])
def test_bandwidth_of_hand_made_block_patterns(where, expected):
    assert bandwidth(_blocks(2, where)) == expected


def test_a_steering_loop_in_the_units_of_its_table():
    (c,) = jb.load_scene("three-roller-steered").control
    got = loop_info(c, 0.02)
    assert got == dict(actuator="roller 2", axis="y", sensor_mm=[1430.0, 200.0], kp_mrad_per_mm=2.0,
                       ki_mrad_per_mm_s=0.5, kd_mrad_s_per_mm=0.0, sample_s=0.04,
                       limit_mrad=pytest.approx(3.0), rate_limit_mrad_s=pytest.approx(5.0), lag_s=0.05,
                       setpoint_mm=0.0, noise_um=pytest.approx(2.0),
                       edge_profile_um=[[1, pytest.approx(4.0), 0.3], [3, pytest.approx(2.0), 1.1]])
    every_step = loop_info(dataclasses.replace(c, sample=None, rate_limit=None, setpoint=-1.5e-3), 0.02)
    assert every_step["sample_s"] == 0.02 and every_step["rate_limit_mrad_s"] is None
    assert every_step["setpoint_mm"] == pytest.approx(-1.5)


def _choices(mutate, name="two-roller-1d"):
    scene = scene_with(mutate, name)
    return automatic_choices(scene, jb.build_mesh(scene))


def test_automatic_choices_of_a_1d_scene():
    grid, precision = _choices(lambda d: None)
    assert grid.startswith("grid: the scene's own (--accuracy-um") and precision.startswith("precision: float64")
    grid, _ = _choices(lambda d: d.update(solver={"accuracy_um": 2.5}))
    assert grid.startswith("grid: chosen for 2.5 µm when the scene runs")
    _, _, reuse = _choices(lambda d: d.update(solver={"linear_solver": "reuse"}))
    assert reuse.startswith("reuse solver: no refinement (shift transport, no lateral transport")
    _, _, reuse = _choices(lambda d: d.update(solver={"linear_solver": "reuse", "transport": "source"}))
    assert reuse == "reuse solver: 2 refinement iterations a step (the step matrix drifts)"


def test_automatic_choices_of_a_2d_scene_say_the_model_and_the_tension_stiffening():
    two_d = {"model": {"kind": "2d"}}
    _, _, model, stiffening = _choices(lambda d: d.update(two_d))
    assert model.startswith("model: 2D; with an accuracy asked, simulate runs the 1D counterpart where the models' "
                            "measured difference fits (nothing pushes the belt sideways")
    assert stiffening == "tension stiffening: on, idle here (no pre-tension and no tension roller: nothing to stiffen)"
    _, _, model, stiffening = _choices(lambda d: (d.update(two_d), d["belt"].update(length_mm=863.0),
                                                  d["roller"][1].update(rotation_mrad=[0.0, 1.0, 0.0])))
    assert model == "model: 2D (lateral physics: roller 'idle' tilted)"
    assert stiffening == "tension stiffening: on, acting (tension in the belt)"
    *_, stiffening = _choices(lambda d: (d.update(two_d), d.update(solver={"tension_stiffening": False})))
    assert stiffening == "tension stiffening: off"
