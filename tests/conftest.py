import os

import jax

jax.config.update("jax_enable_x64", True)

# No persistent compilation cache in the test suite (the CLI has it on by default): tests must
# not depend on what an earlier run left in ~/.cache.
os.environ["JAXBELT_COMPILATION_CACHE"] = "0"


import gc

import pytest


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
