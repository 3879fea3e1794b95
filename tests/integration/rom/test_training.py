"""One reduced model over a box of misalignments: the axial training design and
``jaxbelt reduce --train-ranges`` (1D, short runs), with the honest timing block."""

import json

import numpy as np
import pytest

import jaxbelt as jb
from helpers import TWO_ROLLER_BOX
from jaxbelt.cli import main
from jaxbelt.rom import axial_design, box_from_distribution, position_in_box

@pytest.fixture(scope="module")
def box_file(tmp_path_factory):
    p = tmp_path_factory.mktemp("box") / "box.toml"
    p.write_text(TWO_ROLLER_BOX)
    return str(p)


def test_axial_design_is_the_aligned_machine_and_each_component_at_plus_minus_h():
    m = jb.load_model("two-roller-1d-train1")
    models, thetas, space = axial_design(m, ["drive:dx", "idle:dx"], [12.0, 6.0])
    assert len(models) == 5 and thetas.shape == (5, 2)
    chi = np.stack([np.asarray(x.chi_static)[list(space.chi_index)] for x in models]) * 1e3
    np.testing.assert_allclose(chi, thetas, atol=1e-12)
    np.testing.assert_allclose(chi, [[0, 0], [12, 0], [-12, 0], [0, 6], [0, -6]], atol=1e-12)
    where, unvaried = position_in_box(m, space, [12.0, 6.0])  # train1: the drive at -10 mm
    np.testing.assert_allclose(where, [-10 / 12, 0.0], atol=1e-12)
    assert unvaried == []
    with pytest.raises(ValueError, match="positive"):
        axial_design(m, ["drive:dx"], [0.0])


def test_box_from_a_distribution_takes_half_widths_and_three_sigma():
    from jaxbelt.design.sampling import Distribution

    d = Distribution(("a:dx", "b:dx"), ("uniform", "normal"), (2.0, 0.5))
    np.testing.assert_allclose(box_from_distribution(d), [2.0, 1.5])


def test_reduce_over_a_box_predicts_a_configuration_inside_it(box_file, capsys):
    assert main(["reduce", "two-roller-1d-train1", "--method", "pod", "--train-ranges", box_file,
                 "--steps", "200", "--train-steps", "100", "--stride", "0", "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["rmse_um"] < 20  # the source's tolerance; measured 1 µm at 400 steps
    assert "axial design" in r["train"][0] and "5 runs" in r["train"][0]
    t = r["timings"]
    # every speedup is against the fastest full mode, timed in the same process
    assert t["full_run_s"] == min(f["run_s"] for f in t["full_runs"])
    assert t["speedup_total"] == pytest.approx(t["full_run_s"] / (t["offline_s"] + t["online_s"]))
    assert t["speedup_total_vs_scene_mode"] == pytest.approx(t["scene_mode_run_s"] / (t["offline_s"] + t["online_s"]))
    assert t["offline_first_call_s"] > 0 and t["speedup_eq_7_5"] > 0


def test_reduce_over_a_box_rejects_bad_combinations(box_file, tmp_path, capsys):
    assert main(["reduce", "two-roller-1d-train1", "--method", "pod", "--train-ranges", box_file,
                 "--train", "two-roller-1d"]) == 2
    assert "exclude each other" in capsys.readouterr().err
    assert main(["reduce", "two-roller-1d-train1", "--method", "dmd", "--train-ranges", box_file]) == 2
    bad = tmp_path / "bad.toml"
    bad.write_text('[roller."nope"]\ntranslation_mm = {dist = "uniform", half_width = [1.0, 0.0, 0.0]}\n')
    assert main(["reduce", "two-roller-1d-train1", "--method", "pod", "--train-ranges", str(bad)]) == 2
    assert "no roller of that name" in capsys.readouterr().err


def test_reduce_warns_when_the_scene_lies_outside_the_box(tmp_path, capsys):
    small = tmp_path / "small.toml"
    small.write_text('[roller."drive"]\ntranslation_mm = {dist = "uniform", half_width = [5.0, 0.0, 0.0]}\n')
    main(["reduce", "two-roller-1d-train1", "--method", "pod", "--train-ranges", str(small),
          "--steps", "60", "--train-steps", "30", "--stride", "0", "--json"])
    err = capsys.readouterr().err
    assert "jaxbelt: warning: two-roller-1d-train1 lies outside the training box" in err  # one line
