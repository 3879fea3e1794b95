"""The tolerance-design commands: ``sensitivity``, ``tolerance``, ``sweep`` (JSON, plots, store)
and their one-line errors for bad input.

On a coarse scene (two grid lines across, 12 steps: a whole number of the scan's checkpoint
chunks, so each compiled run holds one copy of the step); ``sensitivity``, ``tolerance`` and
``sweep`` with ``--solver reuse`` (the factorisation-reuse solver: cheaper to compile and to run)."""

import json
import math

import pytest

from jaxbelt.cli import main

SMALL = """extends = "three-roller-tolerance"
[mesh]
n_eta = 2
[time]
t_end_s = 0.24
"""
DIST = """[roller."roller 2"]
rotation_mrad = {dist = "normal", sigma = [0.05, 0.05, 0.0]}
"""


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("design_cli")
    (d / "small.toml").write_text(SMALL)
    (d / "dist.toml").write_text(DIST)
    return d


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_sensitivity_json_and_plot(files, capsys):
    r = _json(capsys, ["sensitivity", str(files / "small.toml"), "--metric", "lateral_max", "--solver", "reuse",
                       "--json", "--plot", str(files / "s.png")])
    assert r["metric"] == "lateral_max" and r["at_kink"] and r["value_um"] < 1e-6
    assert set(r["gradient"]) == {"roller 1", "roller 2", "roller 3"}
    # a roller moved along its axis carries the belt with it: ~1 µm per µm
    assert 900 < r["gradient"]["roller 3"]["translation_um_per_mm"][2] < 1100
    assert all(g["rotation_um_per_mrad"][2] == 0.0 for g in r["gradient"].values())
    assert r["forward_s"] > 0 and r["gradient_s"] > 0 and (files / "s.png").stat().st_size > 0


def test_tolerance_json(files, capsys):
    """The tolerance box verified by full runs (the fast version of
    design/test_tolerance.py::test_box_on_the_default_scene_is_verified_by_full_runs)."""
    (files / "w.toml").write_text('[roller."roller 2"]\nrotation = [4.0, 1.0, 1.0]\n')
    r = _json(capsys, ["tolerance", str(files / "small.toml"), "--components", "roller 2:rotation",
                       "--weights", str(files / "w.toml"), "--solver", "reuse", "--json", "--plot", str(files / "t.png")])
    assert r["verified"] and 0.97 * 20 <= r["worst_case_um"] <= 20
    ax, ay = r["box"]["roller 2"]["rotation_mrad"][:2]
    assert ax > 0 and ay > 0 and r["box"]["roller 1"]["rotation_mrad"] == [0.0, 0.0, 0.0]
    assert r["binding"] and all(v["full_um"] <= 20 for v in r["verification"])
    assert max(v["full_um"] for v in r["verification"]) == r["worst_case_um"]
    assert set(r["binding"]) <= {"roller 2:ax", "roller 2:ay"}
    assert all(h["half_width"] >= 0 and math.isfinite(h["half_width"]) for h in r["half_widths"])
    # error bars: the verified corners on the grid one level finer (elements ×2 along and across, Δt / 2)
    d = r["discretisation"]
    assert d["grid_fine"]["n_xi"] == 2 * d["grid"]["n_xi"] and d["grid_fine"]["dt"] == pytest.approx(d["grid"]["dt"] / 2)
    worst_rows = [v["full_um"] for v in r["verification"] if v["kind"] == "worst corner"]
    assert d["worst_case_um"] == pytest.approx(max(worst_rows)) and d["worst_case_fine_um"] > 0
    change = d["half_width_relative_change"]
    assert 0 < abs(change) < 0.5
    # the worst corner's excess over the floor, scaled back to the verified level on the finer grid
    scale = (d["worst_case_um"] - d["floor_fine_um"]) / (d["worst_case_fine_um"] - d["floor_fine_um"])
    assert change == pytest.approx(scale - 1)
    for h in r["half_widths"]:
        assert h["discretisation_uncertainty"] == pytest.approx(abs(change) * h["half_width"])


def test_sweep_json_store_and_resume(files, capsys):
    out = files / "sweep.zarr"
    argv = ["sweep", str(files / "small.toml"), "--dist", str(files / "dist.toml"), "--samples", "24",
            "--chunk", "8", "--limit-um", "8", "--solver", "reuse", "--out", str(out), "--json", "--no-form"]
    r = _json(capsys, argv + ["--plot", str(files / "y.png")])
    assert r["samples"] == 24 and r["full_runs"] == 24 and r["reduced_runs"] == 0
    assert r["ci95"][0] <= r["yield"] <= r["ci95"][1]
    # the yield's discretisation bias: the samples within 10 % of the limit (at most 16, at least the
    # two nearest) re-run one level finer
    d = r["discretisation"]
    assert 2 <= d["samples"] <= 16 and 0 <= d["flipped"] <= d["samples"] and d["metric_relative_change"] > 0
    assert abs(d["bias"]) <= d["flipped"] / 24 + 1e-12
    again = _json(capsys, argv + ["--no-error-bars"])  # everything already stored: resumes with nothing to run
    assert again["yield"] == r["yield"] and "discretisation" not in again


def test_sweep_form_from_the_study_linearisation_equals_a_plain_study(files, capsys):
    """``sweep`` with FORM takes the Jacobian with its study (``make_study(..., jacobian=True)``):
    its FORM index and RSS stack-up equal those of the library on a plain study, whose Jacobian is
    a run of its own."""
    import tomllib

    import jaxbelt as jb
    from jaxbelt import design

    r = _json(capsys, ["sweep", str(files / "small.toml"), "--dist", str(files / "dist.toml"), "--samples", "8",
                       "--chunk", "8", "--limit-um", "8", "--solver", "reuse", "--json", "--no-error-bars"])
    scene = jb.load_scene(str(files / "small.toml"))
    model, opts = jb.build_model(scene), jb.RunOptions.from_scene(scene)
    dist = design.distribution_from_dict(tomllib.loads((files / "dist.toml").read_text()), model)
    plain = design.make_study(model, r["metric"], opts.replace(solver=jb.make_solver("direct", "reuse")),
                              components=list(dist.labels))
    f = design.form(plain, dist, 8.0)
    assert isinstance(plain, design.Study) and 0 < r["form_beta"] < 10
    assert r["form_beta"] == pytest.approx(f.beta, rel=1e-8)
    r0, J = design.response_jacobian(plain)
    sigma = [v if k == "normal" else v / 3**0.5 for k, v in zip(dist.kind, dist.scale)]
    rss = design.rss_stackup(design.LinearResponse(r0, J, plain.aggregate), sigma).three_sigma_um
    assert r["rss_3sigma_um"] == pytest.approx(rss, rel=1e-8)


BAD = [
    (["tolerance", "{small}", "--limit-um", "0"], "--limit-um"),
    (["tolerance", "{small}", "--limit-um", "nan"], "--limit-um"),
    (["sensitivity", "{small}", "--metric", "lateral_avg"], "--metric"),
    (["tolerance", "{small}", "--components", "roller 7:rotation"], "roller 7"),
    (["sweep", "{small}", "--dist", "{dist}", "--samples", "0"], "--samples"),
    (["sweep", "{small}", "--dist", "{neg}"], "must not be negative"),
    (["sweep", "{small}", "--dist", "{nan}"], "must be finite"),
    (["sweep", "{small}", "--dist", "{gumbel}"], "unknown distribution"),
    (["sweep", "{small}", "--dist", "{missing}"], "no such file"),
    (["sweep", "{small}", "--dist", "{dist}", "--rom", "maybe"], "--rom"),
    (["sensitivity", "{small}", "--at", "-1"], "--at"),
    (["tolerance", "{small}", "--accuracy-um", "0"], "--accuracy-um"),
    (["sweep", "{small}", "--dist", "{dist}", "--accuracy-um", "nan"], "--accuracy-um"),
    (["sensitivity", "{small}", "--accuracy-um", "-2"], "--accuracy-um"),
]


@pytest.mark.parametrize("argv,word", BAD, ids=[w for _, w in BAD])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(files, capsys, argv, word):
    for name, text in (("neg", "[roller.\"roller 2\"]\nrotation_mrad = {dist = \"normal\", sigma = [-0.1, 0, 0]}\n"),
                       ("nan", "[roller.\"roller 2\"]\nrotation_mrad = {dist = \"normal\", sigma = [nan, 0, 0]}\n"),
                       ("gumbel", "[roller.\"roller 2\"]\nrotation_mrad = {dist = \"gumbel\", sigma = [0.1, 0, 0]}\n")):
        (files / f"{name}.toml").write_text(text)
    paths = {k: str(files / f"{k}.toml") for k in ("small", "dist", "neg", "nan", "gumbel", "missing")}
    out = files / "never.zarr"
    argv = [a.format(**paths) for a in argv] + ["--plot", str(files / "never.png")]
    if argv[0] == "sweep":
        argv += ["--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and word in err[0] and "Traceback" not in err[0]
    assert not out.exists() and not (files / "never.png").exists()
