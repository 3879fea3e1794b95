"""Shared benchmark helpers: timing with compile and run apart, JSON output."""

import json
import platform
import time
from pathlib import Path

import jax

RESULTS = Path(__file__).parent / "results"


def timed(fn, *args, repeat=3):
    """``(compile_s, best_run_s, result)`` for a jitted callable: the first call is timed
    separately (compile + run), then the best of ``repeat`` further calls."""
    t0 = time.perf_counter()
    out = jax.block_until_ready(fn(*args))
    first = time.perf_counter() - t0
    runs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = jax.block_until_ready(fn(*args))
        runs.append(time.perf_counter() - t0)
    best = min(runs)
    return max(first - best, 0.0), best, out


def machine():
    import os

    return {"platform": platform.platform(), "python": platform.python_version(), "jax": jax.__version__,
            "device": str(jax.devices()[0]), "cpu_count": os.cpu_count()}


def write(name, payload):
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / f"{name}.json"
    path.write_text(json.dumps({"machine": machine(), **payload}, indent=2))
    print(f"wrote {path}")
    return path


def bar_plot(rows, key, ratio_key, ratio_fmt, xlabel, title, path):
    """Horizontal bars of ``rows[name][key]`` annotated with ``rows[name][ratio_key]``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 3.5), constrained_layout=True)
    names = list(rows)
    ax.barh(names, [rows[n][key] for n in names], color="tab:blue")
    for i, n in enumerate(names):
        ax.text(rows[n][key], i, " " + ratio_fmt.format(rows[n][ratio_key]), va="center")
    ax.set_xlabel(xlabel)
    ax.set_title(title)
    fig.savefig(path, dpi=120)
    plt.close(fig)
