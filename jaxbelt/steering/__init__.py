"""Loop design (model specification §8): the steering loop's plant, its margins and its gains.

Beside :mod:`jaxbelt.design` (tolerance design), above :mod:`jaxbelt.steady` and
:mod:`jaxbelt.timeloop`. One concept per module:

- :mod:`~jaxbelt.steering.transfer`: the transfer abstraction (anything with
  ``frequency_response(ω)``), the loop closed with a PID controller, and the one :func:`margins`;
- :mod:`~jaxbelt.steering.plant`: the identified plant (:class:`SteeringPlant`), its step response,
  and its fits to the model's step response (:func:`identify_plant`, :func:`fit_plant`);
- :mod:`~jaxbelt.steering.response`: the model's measured response as a transfer in continuous time
  (:class:`MeasuredResponse`) and as the sampled loop (:class:`DiscreteLoop`), the one measured
  step response (:func:`open_loop_response`) and the one actuator step (:func:`actuator_step`);
- :mod:`~jaxbelt.steering.report`: ``jaxbelt steering``'s report (coefficient, disturbance, hold
  angle, walk sensitivity from steady walks; the plant; the P loop's stability boundary);
- :mod:`~jaxbelt.steering.tuning`: ``jaxbelt tune`` (PI gains by gradient descent through the run).

The walk rate read off a run is :func:`jaxbelt.control.walk_rate` (also here as :func:`walk_rate`).
"""

from ..control import walk_rate as walk_rate
from .plant import SteeringPlant as SteeringPlant
from .plant import fit_plant as fit_plant
from .plant import identify_plant as identify_plant
from .report import StabilityBoundary as StabilityBoundary
from .report import SteeringReport as SteeringReport
from .report import StepResponse as StepResponse
from .report import LoopGrowth as LoopGrowth
from .report import WalkSensitivity as WalkSensitivity
from .report import SteeringWarning as SteeringWarning
from .report import stability_boundary as stability_boundary
from .report import steering_report as steering_report
from .response import DiscreteLoop as DiscreteLoop
from .response import MeasuredResponse as MeasuredResponse
from .response import actuator_step as actuator_step
from .response import open_loop_response as open_loop_response
from .response import run_batch as run_batch
from .transfer import Transfer as Transfer
from .transfer import loop_response as loop_response
from .transfer import margins as margins
from .transfer import pid_response as pid_response
from .tuning import TuningResult as TuningResult
from .tuning import tune as tune
