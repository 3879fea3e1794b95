"""Test configuration: float64, a compilation cache shared by the xdist workers, compiled
programs freed after each module, and the ``--runslow`` option.

The default run (``python -m pytest``; ``pyproject.toml`` adds ``-m 'not slow' -n 2 --dist
loadfile``) leaves out the slow tests: those whose measured cost is over :data:`SLOW_TEST_S`
(``benchmarks/suite_cost.py`` measures every test and writes ``tests/test_seconds.json``), except
the checks against an independent reference (marked ``reference``), kept whatever they cost.
No test is marked slow by hand. ``python -m pytest --runslow`` runs everything (slow tests
included); ``python -m pytest -m slow`` runs only the slow ones.
"""

import gc
import json
import os
from pathlib import Path

# Compiling dominates the suite (hundreds of whole-run programs, most run for a few dozen steps):
# LLVM at -O0 instead of -O3 compiles ~35 % faster and runs the programs 2–4× slower, a net
# ~25 % less CPU time for the suite (the few long 2D runs use helpers.simulate_optimised).
# XLA:CPU's newer MLIR fusion emitters off (the classic elemental IR emitters instead) halves
# what is left of a compile again (a 1D run 2.1 → 1.2 s, build_model of a 2D scene 3.1 → 1.5 s)
# and does not slow the runs; results agree with the default emitters to round-off (~1e-12
# relative). One LLVM module per program instead of parallel codegen's pieces: ~7 % less again
# (the two workers already keep both cores busy). Set before jax starts its backend; a caller's
# own XLA_FLAGS win, flag by flag, and a flag the installed XLA no longer defines is left out
# (an unknown flag aborts the process).
TEST_XLA_FLAGS = {"xla_backend_optimization_level": "0", "xla_cpu_use_fusion_emitters": "false",
                  "xla_cpu_parallel_codegen_split_count": "1"}

# One BLAS thread per process: the two workers already fill both cores, and OpenBLAS's own
# threads (numpy, scipy, and jaxlib's LAPACK calls through scipy's) only spin waiting for each
# other (an 850 × 850 cond + solve + eigh: 1.4 s CPU single-threaded, 4.7 s with 2 threads under
# load). The variable reaches the libraries loaded from here on (and subprocesses); numpy's is
# loaded already (by pytest's plugins), threadpoolctl (a dependency of pymor) limits it.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
try:
    from threadpoolctl import threadpool_limits

    threadpool_limits(1, user_api="blas")
except ImportError:  # pragma: no cover - threadpoolctl comes with the dev extra
    pass

from jaxbelt.cli import add_xla_flags  # noqa: E402  (imports jax; its backend starts at the first computation)

add_xla_flags(TEST_XLA_FLAGS)

import jax  # noqa: E402
import pytest  # noqa: E402

jax.config.update("jax_enable_x64", True)

# The CLI's persistent compilation cache (~/.cache) stays off in the tests: they must not depend on
# what an earlier run left. Within one run the workers share a fresh cache directory, so a
# program compiled by one module (or one worker) is loaded, not recompiled, by the next (the
# per-module clearing below would otherwise recompile every shared model). Every program is
# kept, however quickly it compiled: build_model alone runs ~150 small eager programs
# (~30 ms each to compile, ~5 ms to load).
os.environ["JAXBELT_COMPILATION_CACHE"] = "0"


def pytest_addoption(parser):
    parser.addoption("--runslow", action="store_true", default=False,
                     help="also run the tests marked slow (the default run leaves them out)")


# xdist's loadfile scheduling hands whole modules to the two workers in collection order; heaviest
# first, so that the run ends on small modules and both workers finish together (pyproject.toml
# turns off xdist's own reordering by test count). Seconds per module as benchmarks/suite_cost.py
# measured them, keyed by the module's path under tests/ without ``.py`` (``integration/design/test_study``:
# the folders mirror the package, so stems repeat); a module not in the table, default 5, only
# costs balance.
TESTS = Path(__file__).parent
MODULE_SECONDS = json.loads((TESTS / "module_seconds.json").read_text())

# The slow/fast split, by measured cost alone: a test whose one-process seconds, as
# benchmarks/suite_cost.py measured them for every test (tests/test_seconds.json), exceed
# SLOW_TEST_S is slow, unless it is marked ``reference`` (a check against an independent reference:
# a dense solve, an analytic solution, python-control — the default run keeps one of each, whatever
# it costs). A test not in the table yet (a new one) runs by default until the next measurement.
TEST_SECONDS_FILE = TESTS / "test_seconds.json"
TEST_SECONDS = json.loads(TEST_SECONDS_FILE.read_text()) if TEST_SECONDS_FILE.exists() else {}
if os.environ.get("JAXBELT_MEASURED_SPLIT", "1") == "0":  # suite_cost.py measures every test
    TEST_SECONDS = {}
SLOW_TEST_S = 1.0  # so that the default run stays under two minutes on two cores


@pytest.hookimpl(tryfirst=True)  # before the mark plugin deselects by ``-m``
def pytest_collection_modifyitems(config, items):
    """Tests over :data:`SLOW_TEST_S` marked slow; modules in decreasing ``MODULE_SECONDS`` (a
    stable sort: each module's own order stays)."""
    for item in items:
        if TEST_SECONDS.get(item.nodeid, 0.0) > SLOW_TEST_S and item.get_closest_marker("reference") is None:
            item.add_marker(pytest.mark.slow)
    items.sort(key=lambda item: -MODULE_SECONDS.get(module_key(item.path), 5))


def module_key(path):
    """A test module's key in ``module_seconds.json``: its path under tests/ without ``.py`` (its
    stem, outside tests/)."""
    return path.relative_to(TESTS).with_suffix("").as_posix() if path.is_relative_to(TESTS) else path.stem


def pytest_configure(config):
    if config.getoption("runslow") and config.option.markexpr.strip() in ("not slow", "'not slow'"):
        config.option.markexpr = ""  # pyproject's addopts say -m 'not slow'; an explicit -m still wins
    _compilation_cache(config)


def _compilation_cache(config):
    """The run's shared compilation-cache directory: made by the controlling process (or the
    only one), inherited by the xdist workers through the environment, removed at the end."""
    if not hasattr(config, "workerinput"):
        import tempfile

        config._jaxbelt_xla_cache = tempfile.mkdtemp(prefix="jaxbelt-test-xla-")
        os.environ["JAXBELT_TEST_XLA_CACHE"] = config._jaxbelt_xla_cache
    path = os.environ.get("JAXBELT_TEST_XLA_CACHE")
    if path:
        jax.config.update("jax_compilation_cache_dir", path)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0)
        jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)


def pytest_unconfigure(config):
    import shutil

    path = getattr(config, "_jaxbelt_xla_cache", None)
    if path:
        shutil.rmtree(path, ignore_errors=True)



@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Free XLA's compiled programs after each test module.

    Every CPU executable holds its own memory mappings; one process that compiles the whole
    suite's programs (≈ 200 mappings a second of compiling) passes the kernel's per-process
    limit (``vm.max_map_count``, 65530 by default) and the next compile segfaults. Clearing JAX's
    caches between modules keeps the count bounded (module-scoped fixtures are torn down first).
    They are cleared only once the process holds more than half the limit: until then the next
    module reuses what this one traced and compiled (the shared scenes' ``build_model`` and
    ``initial_state``, whole runs of the same shapes) instead of tracing it again and loading it
    from the compilation cache. Only then is the garbage collector run too: with the caches
    kept, a full collection walks every cached program's Python objects (~1.5 s a module late
    in a worker's run)."""
    yield
    n, limit = _memory_mappings()
    if n is None or n > limit // 2:
        jax.clear_caches()
        gc.collect()


def _memory_mappings():
    """``(mappings this process holds, the kernel's limit)``; ``(None, None)`` where Linux's
    ``/proc`` does not tell."""
    try:
        with open("/proc/self/maps") as f:
            n = sum(1 for _ in f)
        with open("/proc/sys/vm/max_map_count") as f:
            return n, int(f.read())
    except (OSError, ValueError):
        return None, None
