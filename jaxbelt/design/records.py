"""The small typed records the design results are made of (:mod:`jaxbelt.infra.results`): a
roller's misalignment or half-widths, a roller's sensitivities, one limit of a study with several,
one component's gradient, one structurally zero component, a surrogate's validation.

Per-roller tables are mappings ``{roller name: record}`` in the rollers' order, every roller of
the model present (components that are not parameters read 0), so that their JSON is
``{"roller 1": {"translation_mm": [x, y, z], "rotation_mrad": [x, y, z]}, ...}``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..infra.results import Result, in_metric_unit, json_fields, to_json, unit_field
from ..misalignment import TRANSLATIONS, ParameterSpace


@dataclasses.dataclass(frozen=True)
class RollerMisalignment(Result):
    """One roller's misalignment components (a corner of a box, a design point) or its
    half-widths (a tolerance box). **Fields:** ``translation_mm`` (3,) along x, y, z, mm;
    ``rotation_mrad`` (3,) about x, y, z, mrad."""

    translation_mm: tuple
    rotation_mrad: tuple


@dataclasses.dataclass(frozen=True)
class RollerSensitivity(Result):
    """One roller's gradient of a metric, in ``unit`` (the metric's: µm; µm/s for ``walk_rate``,
    mrad for ``steering_max``) per mm or mrad. **Fields:** ``translation_um_per_mm`` (3,) per mm
    along x, y, z; ``rotation_um_per_mrad`` (3,) per mrad about x, y, z; ``unit``. Their JSON
    keys name the unit (``translation_mrad_per_mm`` of ``steering_max``)."""

    translation_um_per_mm: tuple = in_metric_unit()
    rotation_um_per_mrad: tuple = in_metric_unit()
    unit: str = unit_field()


def _groups(space: ParameterSpace, values) -> dict[str, tuple[tuple, tuple]]:
    """``{roller: (translation (3,), rotation (3,))}`` of (P,) ``values`` in the units of the
    components; components that are not parameters 0."""
    values = np.asarray(values, float)
    out = {name: ([0.0] * 3, [0.0] * 3) for name in space.roller_names}
    for k, (j, c) in enumerate(space.entries):
        out[space.roller_names[j]][0 if c in TRANSLATIONS else 1]["xyz".index(c[1])] = float(values[k])
    return {name: (tuple(t), tuple(r)) for name, (t, r) in out.items()}


def misalignment_per_roller(space: ParameterSpace, theta) -> dict[str, RollerMisalignment]:
    """``{roller: RollerMisalignment}`` of a design vector or half-widths ``theta`` (P,), mm / mrad."""
    return {name: RollerMisalignment(t, r) for name, (t, r) in _groups(space, theta).items()}


def sensitivity_per_roller(space: ParameterSpace, gradient, unit: str = "µm") -> dict[str, RollerSensitivity]:
    """``{roller: RollerSensitivity}`` of a gradient (P,) in ``unit`` (the metric's) per mm / per mrad."""
    return {name: RollerSensitivity(t, r, unit) for name, (t, r) in _groups(space, gradient).items()}


@dataclasses.dataclass(frozen=True)
class MetricLimit(Result):
    """One limit of a study with several (:func:`jaxbelt.design.study.with_limits`).
    **Fields:** ``metric``; ``limit`` in the metric's ``unit`` (``"µm"``, ``"µm/s"``,
    ``"mrad"``: :func:`jaxbelt.design.metrics.metric_unit`)."""

    metric: str
    limit: float
    unit: str


@dataclasses.dataclass(frozen=True)
class ComponentGradient(Result):
    """A metric's derivative with respect to one varied component. **Fields:** ``component``
    ``"roller:component"``; ``unit`` the component's (``"mm"`` or ``"mrad"``); ``gradient`` the
    metric's unit per that unit."""

    component: str
    unit: str
    gradient: float


@dataclasses.dataclass(frozen=True)
class StructuralZero(Result):
    """A component that cannot vary in the model. **Fields:** ``component``
    ``"roller:component"``; ``reason``."""

    component: str
    reason: str


@dataclasses.dataclass(frozen=True)
class SurrogateValidation(Result):
    """The record of a fitted surrogate (:func:`~jaxbelt.design.surrogate.fit_surrogate`,
    :attr:`~jaxbelt.design.surrogate.Surrogate.validation`).

    **Fields:** ``method`` the reduced model (``"response"`` | ``"pod"``) and ``description`` in
    words; ``validation_runs`` the full runs it took (training + validation), ``training_runs``,
    ``n_validation``; ``seed`` of the validation samples; ``training_widths`` (P,) the training
    widths ``w``, mm / mrad; ``safety`` the factor on the largest validation error; ``rho_max``
    the largest ``ρ`` of a validation sample; ``max_true_error_um``, ``median_true_error_um``
    the metric errors on the validation samples; ``max_bound_um`` the bound there (these and
    ``metric_range_um`` in ``unit``, the metric's, which their JSON keys name);
    ``effectivity_min`` / ``effectivity_median`` bound over true error there (``inf`` where no
    sample has an error); ``loo_effectivity_min`` the leave-one-out check (:mod:`jaxbelt.design.surrogate`);
    ``metric_range_um`` ``[min, max]`` of the validation samples' full metric; ``training_s``,
    ``fit_s``, ``validation_s``, ``offline_s`` the wall times of the parts and of the whole.
    Where they apply (else ``None``, left out of :meth:`to_dict`): ``steps_kept`` the steps the
    response surface keeps; ``snapshots``, ``n_modes``, ``sv_tol``, ``singular_value_ratio`` of
    the POD basis; ``max_true_steering_error_mrad`` and ``steering_bound_mrad`` on a steered
    machine; ``unit`` the metric's."""

    method: str
    description: str
    validation_runs: int
    training_runs: int
    n_validation: int
    seed: int
    training_widths: tuple
    safety: float
    rho_max: float
    max_true_error_um: float = in_metric_unit()
    median_true_error_um: float = in_metric_unit()
    max_bound_um: float = in_metric_unit()
    effectivity_min: float
    effectivity_median: float
    loo_effectivity_min: float
    metric_range_um: tuple = in_metric_unit()
    training_s: float
    fit_s: float
    validation_s: float
    offline_s: float
    steps_kept: int | None = None
    snapshots: int | None = None
    n_modes: int | None = None
    sv_tol: float | None = None
    singular_value_ratio: float | None = None
    max_true_steering_error_mrad: float | None = None
    steering_bound_mrad: float | None = None
    unit: str = unit_field()

    def to_dict(self) -> dict:
        """The record as JSON-able data, the fields that are ``None`` left out, metric values keyed
        by ``unit``."""
        return to_json({k: v for k, v in json_fields(self).items() if v is not None})
