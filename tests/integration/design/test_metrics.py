"""The design metrics (jaxbelt.design.metrics): zero when aligned, equal to their definitions."""

import jax.numpy as jnp
import numpy as np

from jaxbelt import design


def test_metrics_are_zero_for_the_aligned_machine_and_match_their_definitions(study):
    du, dv = design.tracer_deviation(study, jnp.zeros(study.space.size))
    k = study.options.n_steps - 1
    assert np.isclose(float(design.metric_value(study, jnp.zeros(4))), float(jnp.sqrt(jnp.mean(dv[k] ** 2))), rtol=1e-12)
    aligned = design.make_study(study.model.replace(chi_static=jnp.zeros_like(study.base)), "lateral_max",
                                study.options, t_eval=study.t_eval, components="roller 2:rotation")
    assert float(design.metric_value(aligned, jnp.zeros(2))) == 0.0
    peak = design.make_study(study.model, "lateral_peak", study.options, t_eval=study.t_eval,
                             components="roller 2:rotation")
    dv2 = design.tracer_deviation(peak, jnp.zeros(2))[1]
    assert np.isclose(float(design.metric_value(peak, jnp.zeros(2))), float(jnp.max(jnp.abs(dv2[-peak.window:]))))
    assert float(design.metric_value(peak, jnp.zeros(2), smooth=True)) >= float(design.metric_value(peak, jnp.zeros(2)))

