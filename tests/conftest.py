import os

import jax

jax.config.update("jax_enable_x64", True)

# No persistent compilation cache in the test suite (the CLI would switch it on when asked to:
# JAXBELT_COMPILATION_CACHE=1): one full-suite run with it on died in a segfault, see README.
os.environ["JAXBELT_COMPILATION_CACHE"] = "0"
