"""Shared benchmark helpers: timing with compile and run apart, JSON output.

Importing it switches JAX to float64 (:func:`jaxbelt.enable_x64`): the benchmarks measure
jaxbelt as the command line runs it (``float32.py`` sets each child process's precision itself).
"""

import json
import time
from pathlib import Path

import jax

import jaxbelt as jb
from jaxbelt.bench.timing import clock, machine  # noqa: F401  (clock: for the scripts)

jb.enable_x64()

RESULTS = Path(__file__).parent / "results"


def load(source):
    """``(model, run options)`` of a scene (a built-in name or a path, or a :class:`jaxbelt.Scene`)."""
    scene = source if isinstance(source, jb.Scene) else jb.load_scene(source)
    return jb.build_model(scene), jb.RunOptions.from_scene(scene)


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
