import jax

jax.config.update("jax_enable_x64", True)

# The CLI's persistent XLA compilation cache (~/.cache/jaxbelt/xla, JAXBELT_CACHE_DIR;
# JAXBELT_COMPILATION_CACHE=0 switches it off): a second run of the suite skips most compilation.
from jaxbelt.cli import enable_compilation_cache  # noqa: E402

enable_compilation_cache()
