"""jaxbelt: a differentiable JAX simulator of conveyor-belt systems with model order reduction.

Importing jaxbelt changes no process-wide setting. Its results are meant in float64: call
:func:`enable_x64` first (the command line does), or set ``JAX_ENABLE_X64=1`` in the environment
before JAX is imported; without it JAX computes in float32, whose error the float32 benchmark
measures.
"""

from .build import build_model as build_model
from .integrators import CyclicReduction as CyclicReduction
from .integrators import Dense as Dense
from .integrators import DirectBackwardEuler as DirectBackwardEuler
from .integrators import EliminatedBackwardEuler as EliminatedBackwardEuler
from .integrators import KeptInterior as KeptInterior
from .integrators import NaiveBackwardEuler as NaiveBackwardEuler
from .integrators import Reuse as Reuse
from .integrators import Structured as Structured
from .integrators import make_solver as make_solver
from .mesh import Mesh as Mesh
from .mesh import build_mesh as build_mesh
from .misalignment import with_misalignment as with_misalignment
from .model import BeltModel as BeltModel
from .scene import Scene as Scene
from .scene import SceneError as SceneError
from .scene import builtin_scene_names as builtin_scene_names
from .scene import load_scene as load_scene
from .scene import scene_from_dict as scene_from_dict
from .state import BeltState as BeltState
from .state import initial_state as initial_state
from .timeloop import Checkpointed as Checkpointed
from .run_checks import NonFiniteStateError as NonFiniteStateError
from .timeloop import RunOptions as RunOptions
from .timeloop import SaveAt as SaveAt
from .timeloop import Trajectory as Trajectory
from .run_checks import check_finite as check_finite
from .timeloop import simulate as simulate
from .transport import transport_step as transport_step

__version__ = "0.1.0"


def enable_x64() -> None:
    """Switch JAX to float64 (``jax_enable_x64``), the precision jaxbelt's results are meant in.

    Call it before creating arrays: values made earlier keep their float32 dtype."""
    import jax

    jax.config.update("jax_enable_x64", True)


def load_model(source) -> BeltModel:
    """Load a scene (path or built-in name) and build its model."""
    return build_model(load_scene(source))
