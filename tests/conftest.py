import gc
import os

import jax
import pytest

jax.config.update("jax_enable_x64", True)

# The CLI's persistent compilation cache (~/.cache) stays off in the tests: they must not depend on
# what an earlier run left. Within one run the workers share a fresh cache directory, so a
# program compiled by one module (or one worker) is loaded, not recompiled, by the next (the
# per-module clearing below would otherwise recompile every shared model).
os.environ["JAXBELT_COMPILATION_CACHE"] = "0"


def pytest_configure(config):
    """The run's shared compilation-cache directory: made by the controlling process (or the
    only one), inherited by the xdist workers through the environment, removed at the end."""
    if not hasattr(config, "workerinput"):
        import tempfile

        config._jaxbelt_xla_cache = tempfile.mkdtemp(prefix="jaxbelt-test-xla-")
        os.environ["JAXBELT_TEST_XLA_CACHE"] = config._jaxbelt_xla_cache
    path = os.environ.get("JAXBELT_TEST_XLA_CACHE")
    if path:
        jax.config.update("jax_compilation_cache_dir", path)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.2)
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
    caches between modules keeps the count bounded (module-scoped fixtures are torn down first)."""
    yield
    jax.clear_caches()
    gc.collect()
