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
