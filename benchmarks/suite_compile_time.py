"""Where the test suite's time goes: tracing, lowering and XLA compilation per test module.

Runs ``python -m pytest -q`` (the README's test command, two xdist workers) with a plugin that
listens to JAX's monitoring events (``/jax/core/compile/jaxpr_trace_duration``,
``jaxpr_to_mlir_module_duration``, ``backend_compile_duration`` and the compilation cache's) and
writes, per worker, the seconds and counts of each per test; then sums them per module beside
pytest's own durations. ``--summarise DIR`` only sums an earlier run's worker files.
Run: ``python benchmarks/suite_compile_time.py`` (about as long as the suite). Writes
``results/suite_compile_time.json``.
"""

import argparse
import collections
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

from _common import write

ROOT = Path(__file__).resolve().parent.parent
PLUGIN = r'''
import collections, json, os
import jax, pytest
_stats = collections.defaultdict(lambda: [0, 0.0])
_cur = ["<none>"]
def _listener(event, duration, **kw):
    if event.startswith("/jax/core/compile") or event.startswith("/jax/compilation_cache"):
        s = _stats[(_cur[0], event)]
        s[0] += 1; s[1] += duration
jax.monitoring.register_event_duration_secs_listener(_listener)
@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    _cur[0] = item.nodeid
    yield
def pytest_sessionfinish(session):
    wid = os.environ.get("PYTEST_XDIST_WORKER", "main")
    out = {f"{k[0]}|{k[1]}": v for k, v in _stats.items()}
    json.dump(out, open(os.path.join(os.environ["SUITE_COMPILE_DIR"], f"compile_stats_{wid}.json"), "w"))
'''


def summarise(folder: Path, durations_file: Path | None) -> dict:
    per_module = collections.defaultdict(collections.Counter)
    totals, counts = collections.Counter(), collections.Counter()
    for f in sorted(folder.glob("compile_stats_gw*.json")):
        for key, (n, t) in json.loads(f.read_text()).items():
            node, event = key.split("|")
            event = event.split("/")[-1]
            module = node.split("::")[0].split("/")[-1]
            per_module[module][event] += t
            totals[event] += t
            counts[event] += n
    wall = collections.Counter()
    if durations_file and durations_file.exists():
        for line in durations_file.read_text().splitlines():
            m = re.match(r"([\d.]+)s (call|setup|teardown)\s+tests/(\w+\.py)::", line)
            if m:
                wall[m[3]] += float(m[1])
    modules = {m: {"test_seconds": round(wall.get(m, 0.0), 2), **{e: round(t, 2) for e, t in c.items()}}
               for m, c in per_module.items()}
    compile_s = sum(totals[e] for e in ("jaxpr_trace_duration", "jaxpr_to_mlir_module_duration",
                                        "backend_compile_duration"))
    return {"events_seconds": {e: round(t, 1) for e, t in totals.items()}, "events_count": dict(counts),
            "test_seconds_total": round(sum(wall.values()), 1), "trace_lower_compile_seconds": round(compile_s, 1),
            "modules": dict(sorted(modules.items(), key=lambda kv: -kv[1]["test_seconds"]))}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--summarise", type=Path, default=None, help="a folder of an earlier run's worker files")
    a = ap.parse_args()
    if a.summarise:
        folder, durations = a.summarise, a.summarise / "durations.txt"
    else:
        folder = Path(tempfile.mkdtemp(prefix="suite-compile-"))
        (folder / "suite_compile_plugin.py").write_text(PLUGIN)
        env = {**os.environ, "SUITE_COMPILE_DIR": str(folder), "OPENBLAS_NUM_THREADS": "1",
               "PYTHONPATH": os.pathsep.join([str(folder), os.environ.get("PYTHONPATH", "")])}
        out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p",
                              "suite_compile_plugin", "--durations=0"], cwd=ROOT, env=env, capture_output=True, text=True)
        durations = folder / "durations.txt"
        durations.write_text(out.stdout)
        print(out.stdout.splitlines()[-1] if out.stdout else out.stderr[-2000:])
    res = summarise(folder, durations)
    print(json.dumps({k: v for k, v in res.items() if k != "modules"}, indent=1))
    write("suite_compile_time", res)


if __name__ == "__main__":
    main()
