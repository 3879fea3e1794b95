"""Scene loading, units, and every rejection of a bad scene file (the model specification, §1)."""

import math

import numpy as np
import pytest

import jaxbelt as jb
from helpers import builtin_dict, scene_with


def _reject(mutate, *fragments, name="two-roller-1d"):
    with pytest.raises(jb.SceneError) as e:
        jb.build_model(scene_with(mutate, name))
    msg = str(e.value)
    for f in fragments:
        assert f in msg, msg
    return msg


def test_builtin_scenes_load_and_compile():
    names = jb.builtin_scene_names()
    assert "two-roller-1d" in names and "two-roller-1d-train1" in names and "two-roller-1d-train2" in names
    for n in names:
        m = jb.load_model(n)
        assert m.n_unknowns == m.n_xi * m.block + m.n_roller_dofs
        # the coupling of one node column to the next reaches coupling_band diagonals, no further
        # (the Thomas sweeps keep it banded)
        i, j = np.nonzero(np.any(np.asarray(m.K_lower) != 0, axis=0) | np.any(np.asarray(m.K_upper) != 0, axis=0))
        assert np.max(np.abs(i - j), initial=0) == m.coupling_band, n
        # a tilt's column of R lives on its own roller's belt columns (the exact mode's sweeps skip the rest)
        from jaxbelt.integrators.linear import lever_columns, roller_column_blocks

        cols = lever_columns(m)[0]
        for c, blocks in zip(cols, roller_column_blocks(m, cols)):
            nz = np.flatnonzero(np.abs(np.asarray(m.R)[:, :, c]).max(1) + np.abs(np.asarray(m.R_dz)[:, :, c]).max(1))
            assert len(nz) and set(nz) - {0} <= {k + 1 for k in blocks}, (n, c)


def test_units_are_converted_to_si():
    sc = jb.load_scene("two-roller-1d-train1")
    assert sc.rollers[0].translation == pytest.approx((-0.010, 0.0, 0.0))
    assert sc.rollers[1].center == pytest.approx((0.275, 0.0))
    assert sc.belt.thickness == pytest.approx(1e-4)


def test_unknown_key():
    _reject(lambda d: d["belt"].update(colour="red"), "belt.colour", "unknown key")


def test_unknown_roller_key():
    _reject(lambda d: d["roller"][1].update(spin=3), "roller[1].spin", "unknown key")


def test_unknown_table():
    _reject(lambda d: d.update(physics={}), "physics", "unknown table")


def test_wrong_type():
    _reject(lambda d: d["belt"].update(width_mm="wide"), "belt.width_mm", "'wide'", "number")


def test_wrong_type_vector():
    _reject(lambda d: d["roller"][0].update(center_mm=[0.0]), "roller[0].center_mm", "list of 2")


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_nan_inf(bad):
    _reject(lambda d: d["belt"].update(youngs_modulus_pa=bad), "belt.youngs_modulus_pa", "finite")


def test_nan_in_vector():
    _reject(lambda d: d["roller"][1].update(translation_mm=[math.nan, 0, 0]), "roller[1].translation_mm", "finite")


@pytest.mark.parametrize("key", ["width_mm", "thickness_mm", "youngs_modulus_pa", "density_kg_m3"])
def test_non_positive_material(key):
    _reject(lambda d: d["belt"].update({key: 0.0}), f"belt.{key}", "positive")


def test_non_positive_roller_mass():
    _reject(lambda d: d["roller"][1].update(mass_kg=-1.0), "roller[1].mass_kg", "positive")


def test_poisson_out_of_range():
    _reject(lambda d: d["belt"].update(poisson_ratio=0.5), "belt.poisson_ratio")


def test_cfl_violation():
    msg = _reject(lambda d: d["time"].update(dt_s=0.01), "time.dt_s", "CFL")
    assert "0.007854" in msg  # the largest admissible dt is reported: ℓ_min / V


def test_too_few_elements_on_arc():
    _reject(lambda d: d["mesh"].update(roller_elements=[4, 40]), "element(s) on the arc", "'drive'", "at least 5")


def test_too_few_elements_on_arc_from_element_length():
    def m(d):
        d["mesh"] = {"element_length_mm": 40.0}
        d["time"]["dt_s"] = 0.001
    _reject(m, "mesh.element_length_mm", "at least 5")


def test_belt_wider_than_roller():
    _reject(lambda d: d["roller"][1].update(width_mm=40.0), "roller[1].width_mm", "narrower than the belt")


def test_overlapping_rollers():
    _reject(lambda d: d["roller"][1].update(center_mm=[90.0, 0.0]), "roller[1].center_mm", "overlaps")


def test_too_few_rollers():
    _reject(lambda d: d.update(roller=d["roller"][:1]), "roller", "2 to 6")


def test_too_many_rollers():
    def m(d):
        base = d["roller"][1]
        d["roller"] = [d["roller"][0]] + [dict(base, name=f"r{k}", center_mm=[275.0 * k, 0.0]) for k in range(1, 7)]
    _reject(m, "roller", "2 to 6")


def test_impossible_path_concave_internal_roller():
    # three rollers on a line, the middle one smaller and internal: the belt would have to wrap it
    # from the inside of a concave bend
    def m(d):
        r3 = dict(d["roller"][1], name="third", center_mm=[400.0, 0.0])
        d["roller"][1].update(center_mm=[200.0, 0.0], radius_mm=40.0)
        d["roller"].append(r3)
        d["mesh"] = {"element_length_mm": 4.0}
    _reject(m, "impossible belt path", "simple loop")


def test_external_roller_in_concave_bend_is_fine():
    def m(d):
        r3 = dict(d["roller"][1], name="third", center_mm=[400.0, 0.0])
        d["roller"][1].update(center_mm=[200.0, -30.0], radius_mm=20.0, side="external")
        d["roller"].append(r3)
        d["mesh"] = {"element_length_mm": 1.5}
        d["time"]["dt_s"] = 0.002
    model = jb.build_model(scene_with(m))
    assert model.n_rollers == 3


def test_belt_longer_than_path():
    _reject(lambda d: d["belt"].update(length_mm=900.0), "belt.length_mm", "longer than the belt path")


def test_no_drive():
    _reject(lambda d: d["roller"][0].update(role="idle") or d["roller"][0].pop("speed_m_s"), "drive")


def test_tension_roller_needs_force():
    _reject(lambda d: d["roller"][1].update(role="tension"), "roller[1].force_n", "non-zero force")


def test_force_and_translation_on_same_dof():
    def m(d):
        d["roller"][1].update(role="tension", force_n=[10.0, 0, 0], translation_mm=[1.0, 0, 0])
    _reject(m, "roller[1].translation_mm", "force-loaded")


def test_1d_rejects_tilt():
    _reject(lambda d: d["roller"][1].update(rotation_mrad=[0.4, 0, 0]), "roller[1].rotation_mrad", "2d")


def test_unknown_role_and_side():
    _reject(lambda d: d["roller"][1].update(role="free"), "roller[1].role", "drive, idle, tension")
    _reject(lambda d: d["roller"][1].update(side="inside"), "roller[1].side")


def test_unknown_builtin_and_missing_file(tmp_path):
    with pytest.raises(jb.SceneError, match="unknown scene"):
        jb.load_scene("no-such-scene")
    with pytest.raises(jb.SceneError, match="does not exist"):
        jb.load_scene(tmp_path / "missing.toml")


def test_invalid_toml(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("[belt\nwidth_mm = 3")
    with pytest.raises(jb.SceneError, match="not valid TOML"):
        jb.load_scene(p)


def test_toml_file_roundtrip(tmp_path):
    import tomllib
    from importlib import resources

    text = (resources.files("jaxbelt") / "scenes" / "two-roller-1d.toml").read_text()
    p = tmp_path / "mine.toml"
    p.write_text(text)
    sc = jb.load_scene(p)
    assert sc.name == "mine" and tomllib.loads(text)["mesh"]["free_elements"] == [70, 70]
    assert builtin_dict()["roller"][0]["role"] == "drive"


def test_translated_rollers_must_not_overlap():
    # centres 275 mm apart, radii 50 mm: a 200 mm inward translation of the idle roller overlaps the drive
    _reject(lambda d: d["roller"][1].update(translation_mm=[-200.0, 0.0, 0.0]), "roller[1].translation_mm",
            "with the static translations", "overlaps")


def test_drives_at_two_speeds():
    def m(d):
        d["roller"][1].update(role="drive", speed_m_s=0.4)
    _reject(m, "roller.speed_m_s", "same surface speed")


def test_two_drives_at_one_speed_load():
    d = builtin_dict("two-roller-1d")
    speed = next(r["speed_m_s"] for r in d["roller"] if r["role"] == "drive")
    for r in d["roller"]:
        r.update(role="drive", speed_m_s=speed)
    assert [r.role for r in jb.scene_from_dict(d).rollers] == ["drive", "drive"]


def test_roller_name_must_be_a_string():
    _reject(lambda d: d["roller"][1].update(name=5), "roller[1].name", "non-empty string")


def test_unreadable_scene_files(tmp_path):
    with pytest.raises(jb.SceneError, match="is a folder"):
        jb.load_scene(tmp_path)
    with pytest.raises(jb.SceneError, match="no scene given"):
        jb.load_scene("")
    p = tmp_path / "latin.toml"
    p.write_bytes(b"\xff\xfe[model]\n")
    with pytest.raises(jb.SceneError, match="not UTF-8"):
        jb.load_scene(p)
