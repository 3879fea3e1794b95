"""Tolerance design (model specification §6): metrics, studies, sensitivities, tolerance boxes, yield.

Sits above :mod:`jaxbelt.timeloop` and :mod:`jaxbelt.rom` and is never imported by them.

```python
import jaxbelt as jb
from jaxbelt import design

jb.enable_x64()
scene = jb.load_scene("three-roller-t72")
opts = jb.RunOptions.from_scene(scene)
study, linear = design.make_study(jb.build_model(scene), "lateral_max", opts, t_eval=2.0, jacobian=True)
design.sensitivity_report(study)                      # value + gradient per roller component
box = design.tolerance_box(study, limit_um=20.0, linear=linear)  # largest verified tolerance box
dist = design.Distribution(tuple(study.space.labels()), ("normal",) * study.space.size,
                           tuple(box.half_widths / 3))
design.run_sweep(study, dist, n=1000, limit_um=20.0, linear=linear)  # Monte-Carlo yield, FORM, IS
```

The study holds the question and what its runs read; the linear response at the scene's own
misalignment (:class:`LinearDeviation`, from ``jacobian=True`` or :func:`linearise`) is passed
beside it to what reads it, and computed by a run where it is not given.

Every result is a frozen dataclass with documented fields (:class:`SweepResult`,
:class:`ToleranceBox`, :class:`SensitivityReport`, :class:`MonteCarloResult`,
:class:`FormResult`, :class:`ImportanceSamplingResult`), made of typed records
(:mod:`jaxbelt.design.records`); the command line's JSON is their ``to_dict()``
(:mod:`jaxbelt.infra.results`). Loop design (the steering plant, its margins and
gains) is :mod:`jaxbelt.steering`.
"""

from ..misalignment import COMPONENTS as COMPONENTS
from ..misalignment import ParameterSpace as ParameterSpace
from ..misalignment import parameter_space as parameter_space
from .linearisation import LinearDeviation as LinearDeviation
from .linear_box import LinearResponse as LinearResponse
from .linear_box import Stackup as Stackup
from .linear_box import optimise_box as optimise_box
from .linear_box import rss_stackup as rss_stackup
from .linear_box import worst_case as worst_case
from .metrics import METRICS as METRICS
from .metrics import Metric as Metric
from .metrics import metric_unit as metric_unit
from .records import ComponentGradient as ComponentGradient
from .records import MetricLimit as MetricLimit
from .records import RollerMisalignment as RollerMisalignment
from .records import RollerSensitivity as RollerSensitivity
from .records import StructuralZero as StructuralZero
from .study import Study as Study
from .study import evaluate as evaluate
from .study import linearise as linearise
from .study import make_study as make_study
from .study import make_study_at as make_study_at
from .configurations import at_configurations as at_configurations
from .configurations import evaluate_configs as evaluate_configs
from .configurations import evaluate_metric as evaluate_metric
from .study import metric_value as metric_value
from .study import response as response
from .study import run_deviation as run_deviation
from .study import study_on as study_on
from .study import tracer_deviation as tracer_deviation
from .study import with_limits as with_limits
from .sampling import Distribution as Distribution
from .sampling import FormResult as FormResult
from .sampling import ImportanceSamplingResult as ImportanceSamplingResult
from .sampling import MonteCarloResult as MonteCarloResult
from .sampling import SampleOutputs as SampleOutputs
from .sampling import distribution_from_dict as distribution_from_dict
from .sampling import form as form
from .sampling import importance_sampling as importance_sampling
from .sampling import monte_carlo as monte_carlo
from .sampling import wilson_interval as wilson_interval
from .sampling import yield_estimate as yield_estimate
from .sampling import YieldStatistics as YieldStatistics
from .sampling import yield_statistics as yield_statistics
from .sensitivity import SensitivityReport as SensitivityReport
from .sensitivity import response_jacobian as response_jacobian
from .sensitivity import sensitivity_report as sensitivity_report
from .sensitivity import value_and_gradient as value_and_gradient
from ..infra.sharding import batched_map as batched_map
from ..infra.sharding import config_mesh as config_mesh
from ..infra.sharding import distributed_map as distributed_map
from .sweep import ReducedModelUse as ReducedModelUse
from .sweep import SweepResult as SweepResult
from .sweep import run_sweep as run_sweep
from .tolerance import LimitCheck as LimitCheck
from .tolerance import ToleranceBox as ToleranceBox
from .tolerance import VerificationRun as VerificationRun
from .tolerance import tolerance_box as tolerance_box
