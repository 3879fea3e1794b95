"""Steady operation solved directly (:mod:`jaxbelt.steady.fixed_point`: the fixed point of the
machine's one-period map and its derivatives), solves at many configurations and starts of nearby
solves (:mod:`jaxbelt.steady.batches`), the solves' preconditioner
(:mod:`jaxbelt.steady.preconditioner`), and whether the machine can hold a steady state, with the
actuator jitter steady operation leaves out (:mod:`jaxbelt.steady.checks`)."""

from .batches import forward_jacobian as forward_jacobian
from .batches import linear_start as linear_start
from .batches import map_configurations as map_configurations
from .batches import steady_states as steady_states
from .fixed_point import ADJOINT_KRYLOV_RTOL as ADJOINT_KRYLOV_RTOL
from .fixed_point import DEFAULT_MAX_NEWTON as DEFAULT_MAX_NEWTON
from .fixed_point import DEFAULT_TOL_UM as DEFAULT_TOL_UM
from .fixed_point import UNBOUNDED as UNBOUNDED
from .fixed_point import UNIT as UNIT
from .fixed_point import NoSteadyStateError as NoSteadyStateError
from .fixed_point import SteadyState as SteadyState
from .fixed_point import period_steps as period_steps
from .fixed_point import quiet as quiet
from .fixed_point import state_fields as state_fields
from .fixed_point import steady_state as steady_state
from .fixed_point import steady_tangents as steady_tangents
from .fixed_point import steady_walk as steady_walk
from .fixed_point import steady_with_tangents as steady_with_tangents
from .fixed_point import walks as walks
from .preconditioner import MassTransportPreconditioner as MassTransportPreconditioner
from .preconditioner import mass_transport_preconditioner as mass_transport_preconditioner
from .checks import JITTER_TURNS as JITTER_TURNS
from .checks import actuator_jitter as actuator_jitter
from .checks import check_steady as check_steady
