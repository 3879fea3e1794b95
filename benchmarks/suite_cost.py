"""Where the test suite's time goes, and the slow/fast split it sets: every test's measured cost.

Runs the test suite in fresh processes, each with a small pytest plugin that listens to
JAX's compile events (``jax.monitoring``) per test:

* in one process (``-n 0``) with the split off, so that **every** test runs: test seconds, and
  of them the seconds spent tracing to jaxprs, lowering to MLIR and compiling with XLA (a load
  from the run's compilation cache counts as a compile), the number of programs whose compile took
  over half a second, and the slowest modules. Its seconds are ``tests/test_seconds.json``, by
  which ``tests/conftest.py`` marks a test slow (over ``SLOW_TEST_S``, unless it is a
  ``reference`` check): the split is this measurement, no test is marked slow by hand;
* then the default run under that split, in one process, measured again — a test whose programs
  a test now slow used to compile pays for them itself — until no test crosses the split (at most
  ``ROUNDS`` times; its seconds replace the every-test pass's);
* then the README's test command as configured (``pyproject.toml``: two xdist workers), for the
  wall time a user sees and the test seconds of each worker.

``wall_s_if_split_perfectly`` is half of the default run's one-process seconds: the wall time two
workers could reach at best, before start-up and their competition for the two cores (each XLA
compile is multi-threaded). Writes ``results/suite_cost.json`` and ``tests/module_seconds.json``:
the one-process seconds of every test module in the default run, which ``tests/conftest.py``
schedules the workers by (heaviest module first). Takes about 40 minutes on two cores (the slow
tests run once); ``--split-only`` starts from ``tests/test_seconds.json`` instead of running every
test (a few minutes).
Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/suite_cost.py``.
"""

import argparse
import collections
import glob
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import write

ROOT = Path(__file__).resolve().parent.parent
MODULE_SECONDS = ROOT / "tests" / "module_seconds.json"
TEST_SECONDS = ROOT / "tests" / "test_seconds.json"

PLUGIN = r'''
import collections, json, os, time
import jax.monitoring as mon
import pytest

CUR = ["<none>"]
ACC = collections.defaultdict(collections.Counter)
BIG = collections.Counter()
REFERENCE = set()


def _listener(event, secs, **kwargs):
    if event.startswith("/jax/core/compile/"):
        key = event.rsplit("/", 1)[-1]
        ACC[CUR[0]][key] += secs
        if key == "backend_compile_duration" and secs > 0.5:
            BIG[CUR[0]] += 1


mon.register_event_duration_secs_listener(_listener)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    CUR[0] = item.nodeid
    t0 = time.perf_counter()
    yield
    ACC[item.nodeid]["wall"] += time.perf_counter() - t0
    if item.get_closest_marker("reference") is not None:
        REFERENCE.add(item.nodeid)


def pytest_sessionfinish(session):
    if not ACC:  # xdist's controlling process runs no test
        return
    out = os.environ["SUITE_COST_OUT"]
    wid = os.environ.get("PYTEST_XDIST_WORKER", "main")
    with open(os.path.join(out, f"{wid}.json"), "w") as f:
        json.dump({"tests": ACC, "big": BIG, "reference": sorted(REFERENCE)}, f)
'''

PHASES = {"jaxpr_trace_duration": "trace_s", "jaxpr_to_mlir_module_duration": "lower_s",
          "backend_compile_duration": "xla_compile_s"}


def _run(extra_args, plugin_dir, out_dir, measured_split=True):
    path = os.pathsep.join(p for p in (str(plugin_dir), os.environ.get("PYTHONPATH", "")) if p)
    env = dict(os.environ, SUITE_COST_OUT=str(out_dir), OPENBLAS_NUM_THREADS="1", PYTHONPATH=path,
               JAXBELT_MEASURED_SPLIT="1" if measured_split else "0")
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "suite_cost_plugin", *extra_args], cwd=ROOT,
                       env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    summary = r.stdout.strip().splitlines()[-1] if r.stdout.strip() else ""
    if r.returncode and " failed" not in summary:  # a failing test is still measured; a broken run is not
        raise RuntimeError(f"the suite did not run: {(r.stdout + r.stderr).strip().splitlines()[-3:]}")
    if r.returncode:
        failed = [ln for ln in r.stdout.splitlines() if ln.startswith("FAILED")]
        print("  failing tests (their seconds are measured all the same):\n  " + "\n  ".join(failed),
              file=sys.stderr, flush=True)
    workers = {}
    for path in glob.glob(str(out_dir / "*.json")):
        workers[Path(path).stem] = json.loads(Path(path).read_text())
    return wall, summary, workers


def _totals(workers):
    tot = collections.Counter()
    by_module = collections.Counter()
    big = 0
    for w in workers.values():
        big += sum(w["big"].values())
        for test, c in w["tests"].items():
            for k, v in c.items():
                tot[k] += v
            by_module[re.sub(r"::.*", "", test).removeprefix("tests/")] += c.get("wall", 0.0)  # integration/design/test_study.py
    out = {"test_s": tot["wall"], **{PHASES[k]: tot[k] for k in PHASES}}
    out["compile_share"] = sum(tot[k] for k in PHASES) / tot["wall"]
    out["other_s"] = tot["wall"] - sum(tot[k] for k in PHASES)
    out["programs_over_half_a_second"] = big
    out["slowest_modules_s"] = dict(by_module.most_common(10))
    out["module_s"] = dict(by_module)
    out["per_test_s"] = {test: c.get("wall", 0.0) for w in workers.values() for test, c in w["tests"].items()}
    out["test_s_by_process"] = {k: sum(c.get("wall", 0.0) for c in w["tests"].values())
                                for k, w in sorted(workers.items())}
    return out


def _slow_test_s() -> float:
    """``SLOW_TEST_S`` of ``tests/conftest.py``."""
    return float(re.search(r"^SLOW_TEST_S = ([0-9.]+)", (ROOT / "tests" / "conftest.py").read_text(), re.M).group(1))


ROUNDS = 4  # at most this many one-process default runs to settle the split


def _kept(per_test, reference, slow_s) -> dict:
    return {t: v for t, v in per_test.items() if v <= slow_s or t in reference}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--split-only", action="store_true",
                    help="start from tests/test_seconds.json (an earlier every-test pass) instead of running every test")
    args = ap.parse_args(argv)
    slow_s = _slow_test_s()
    results, reference = {"slow_test_s": slow_s}, set()
    with tempfile.TemporaryDirectory(prefix="jaxbelt-suite-cost-") as d:
        d = Path(d)
        (d / "suite_cost_plugin.py").write_text(PLUGIN)

        def run(label, extra, measured_split):
            out = d / label
            out.mkdir()
            print(f"running the suite: {label}", file=sys.stderr, flush=True)
            wall, summary, workers = _run(extra, d, out, measured_split=measured_split)
            reference.update(t for w in workers.values() for t in w.get("reference", []))
            print(f"  {wall:.1f} s: {summary}", file=sys.stderr, flush=True)
            return {"wall_s": wall, "pytest_summary": summary, **_totals(workers)}

        if args.split_only:
            per_test = json.loads(TEST_SECONDS.read_text())
            earlier = ROOT / "benchmarks" / "results" / "suite_cost.json"  # the pass those seconds came from
            if earlier.exists():
                prev = json.loads(earlier.read_text())
                if "every_test" in prev or "one_process" in prev:
                    results["every_test"] = prev.get("every_test", prev.get("one_process"))
        else:  # every test in one process, the split off: the cost of each
            results["every_test"] = run("every_test", ["-n", "0"], False)
            per_test = dict(results["every_test"]["per_test_s"])
        # the default run under the split, in one process, measured again until no test crosses the
        # split: a test whose programs a test now slow used to compile pays for them itself
        results["rounds"] = []
        for k in range(ROUNDS):
            TEST_SECONDS.write_text(json.dumps({t: round(v, 2) for t, v in sorted(per_test.items())}, indent=1)
                                    + "\n")
            one = run(f"default_one_process_{k}", ["-n", "0"], True)
            measured = one["per_test_s"]
            crossed = sorted(t for t, v in measured.items() if v > slow_s and t not in reference)
            per_test.update(measured)
            results["rounds"].append({"tests": len(measured), "test_s": one["test_s"], "crossed_the_split": crossed})
            if not crossed:
                break
        TEST_SECONDS.write_text(json.dumps({t: round(v, 2) for t, v in sorted(per_test.items())}, indent=1) + "\n")
        results["default_one_process"] = one
        results["two_workers"] = run("two_workers", [], True)
    kept = _kept(per_test, reference, slow_s)
    results["default_run"] = {"tests": len(kept), "slow_tests": len(per_test) - len(kept),
                              "references_over_the_split": sorted(t for t in reference if per_test.get(t, 0) > slow_s)}
    results["wall_s_if_split_perfectly"] = one["test_s"] / 2
    module_s = one["module_s"]
    for r in results.values():
        if isinstance(r, dict):
            r.pop("module_s", None)
            r.pop("per_test_s", None)
    write("suite_cost", results)
    # the scheduling table tests/conftest.py reads: seconds per test module of the default run (its
    # path under tests/ without .py, tests/conftest.py: module_key), one process, measured
    table = {m.removesuffix(".py"): max(1, round(v)) for m, v in sorted(module_s.items(), key=lambda kv: -kv[1])}
    MODULE_SECONDS.write_text(json.dumps(table, indent=1) + "\n")
    print(f"wrote {MODULE_SECONDS} and {TEST_SECONDS}", file=sys.stderr)
    print(json.dumps({k: v for k, v in one.items() if k not in ("slowest_modules_s", "per_test_s", "module_s")},
                     indent=1))


if __name__ == "__main__":
    main()
