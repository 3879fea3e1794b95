"""jaxbelt: a differentiable JAX simulator of conveyor-belt systems with model order reduction.

float64 is switched on at import (``jax_enable_x64``); set the environment variable
``JAXBELT_X64=0`` before importing to keep JAX's float32 default.
"""

import os as _os

# One OpenBLAS thread unless the user chose otherwise: the LAPACK calls behind jnp.linalg (SVD,
# QR, eig of the reduced models; SciPy's OpenBLAS, which jaxlib's CPU kernels use) spin extra
# threads against XLA's own pool: on a busy 2-core machine a 448 x 100 SVD takes 20 ms instead of
# 2 ms (benchmarks/openblas_threads.py, load 5). Read when that OpenBLAS loads (lazily, at the first
# LAPACK call): it has no effect if SciPy's LAPACK was used before jaxbelt was imported.
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import jax as _jax

if _os.environ.get("JAXBELT_X64", "1") != "0":
    _jax.config.update("jax_enable_x64", True)

from .integrators import DirectBackwardEuler as DirectBackwardEuler
from .integrators import EliminatedBackwardEuler as EliminatedBackwardEuler
from .integrators import NaiveBackwardEuler as NaiveBackwardEuler
from .integrators import ReusedFactorisationBackwardEuler as ReusedFactorisationBackwardEuler
from .integrators import make_integrator as make_integrator
from .mesh import Mesh as Mesh
from .mesh import build_mesh as build_mesh
from .model import BeltModel as BeltModel
from .model import compile_scene as compile_scene
from .scene import Scene as Scene
from .scene import SceneError as SceneError
from .scene import builtin_scene_names as builtin_scene_names
from .scene import load_scene as load_scene
from .scene import scene_from_dict as scene_from_dict
from .timeloop import NonFiniteStateError as NonFiniteStateError
from .timeloop import Trajectory as Trajectory
from .timeloop import check_finite as check_finite
from .timeloop import simulate as simulate
from .timeloop import simulate_with_progress as simulate_with_progress
from .state import BeltState as BeltState
from .state import initial_state as initial_state
from .transport import transport_step as transport_step

__version__ = "0.1.0"


def load_model(source) -> BeltModel:
    """Load a scene (path or built-in name) and compile it."""
    return compile_scene(load_scene(source))
