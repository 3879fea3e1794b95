"""The baselines' pure pieces (:mod:`jaxbelt.bench.baselines`) on hand-made figures: the accelerator
results read from a results folder (only the two files it knows), and the figure: one bar per
candidate at its milliseconds per step (jaxbelt's blue, the rest grey, each labelled), and the
per-configuration cost of each solver against the batch size, in batch order."""

import json

import matplotlib

matplotlib.use("Agg")

import matplotlib.figure  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import to_rgba  # noqa: E402

from jaxbelt.bench import baselines  # noqa: E402


def test_accelerator_figures_are_read_from_their_two_files(tmp_path):
    assert baselines.accelerator_figures(tmp_path) is None
    (tmp_path / "gpu_2d_cpu.json").write_text(json.dumps({"ms": 1.0}))  # not an accelerator file
    assert baselines.accelerator_figures(tmp_path) is None
    (tmp_path / "gpu_2d_gpu.json").write_text(json.dumps({"ms_per_step": 0.25}))
    assert baselines.accelerator_figures(tmp_path) == {"gpu_2d_gpu": {"ms_per_step": 0.25}}
    (tmp_path / "full_run_2d_gpu.json").write_text(json.dumps({"run_s": 3.0}))
    assert baselines.accelerator_figures(str(tmp_path)) == {"gpu_2d_gpu": {"ms_per_step": 0.25},
                                                            "full_run_2d_gpu": {"run_s": 3.0}}


PAYLOAD = {
    "scene": "belt", "n_unknowns": 3762,
    "per_step": {"ms_per_step": {"jaxbelt exact step": 2.0, "SuperLU factor + solve (matrix given)": 40.0,
                                 "jaxbelt reuse step": 0.5}},
    "vmap": {"rows": {"reuse/8": dict(solver="reuse", batch=8, ms_per_config_step=0.1),
                      "exact/64": dict(solver="exact", batch=64, ms_per_config_step=0.05),
                      "exact/1": dict(solver="exact", batch=1, ms_per_config_step=1.0),
                      "reuse/1": dict(solver="reuse", batch=1, ms_per_config_step=0.4),
                      "exact/8": dict(solver="exact", batch=8, ms_per_config_step=0.2)}},
}


def _drawn(monkeypatch, tmp_path):
    saved = []
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", lambda fig, path, **kw: saved.append((fig, path)))
    baselines.plot(PAYLOAD, tmp_path / "b.png")
    (fig, path), = saved
    assert path == tmp_path / "b.png" and plt.get_fignums() == []
    return fig


def test_bars_at_the_milliseconds_per_step(monkeypatch, tmp_path):
    bars_ax, _ = _drawn(monkeypatch, tmp_path).axes
    bars = bars_ax.patches
    assert [b.get_width() for b in bars] == [2.0, 40.0, 0.5]
    assert [t.get_text() for t in bars_ax.get_yticklabels()] == list(PAYLOAD["per_step"]["ms_per_step"])
    assert [b.get_facecolor() for b in bars] == [to_rgba("tab:blue"), to_rgba("tab:gray"), to_rgba("tab:blue")]
    assert [t.get_text() for t in bars_ax.texts] == [" 2.00 ms", " 40.00 ms", " 0.50 ms"]
    assert bars_ax.get_xscale() == "log"
    assert bars_ax.get_title() == "belt (N = 3762): jaxbelt (blue) vs SciPy SuperLU"


def test_batch_cost_lines_in_batch_order(monkeypatch, tmp_path):
    _, batch_ax = _drawn(monkeypatch, tmp_path).axes
    exact, reuse = batch_ax.get_lines()
    assert (exact.get_label(), reuse.get_label()) == ("exact", "reuse")
    np.testing.assert_array_equal(exact.get_xdata(), [1, 8, 64])
    np.testing.assert_array_equal(exact.get_ydata(), [1.0, 0.2, 0.05])
    np.testing.assert_array_equal(reuse.get_xdata(), [1, 8])
    np.testing.assert_array_equal(reuse.get_ydata(), [0.4, 0.1])
    assert (batch_ax.get_xscale(), batch_ax.get_yscale()) == ("log", "log")
