"""One interface for the reduced models :func:`~jaxbelt.rom.reduce_and_compare` trains.

A *reduction* (:class:`AbstractReduction`) is a method and its settings — the fully reduced POD
step (:class:`~jaxbelt.rom.pod_step.ReducedPOD`), exact DMD (:class:`~jaxbelt.rom.dmd.DMD`),
DMD with control (:class:`~jaxbelt.rom.dmdc.DMDc`), parametric DMD
(:class:`~jaxbelt.rom.dmdc.ParametricDMD`). Its :meth:`~AbstractReduction.fit` runs the full
model on the training configurations (:class:`TrainingRuns`) and returns a reduced model
(:class:`AbstractReducedModel`), whose :meth:`~AbstractReducedModel.predict` takes a start state
``z0`` (the scaled first-order state ``[x; Δt ẋ]``, m), the configuration parameters ``μ``
(:func:`~jaxbelt.rom.pod_step.parameters`), a step count and the predicted configuration's
tracer operator (:func:`observation`), and returns a :class:`Prediction`: the tracer
displacements and the predicted states in a basis, as the error estimate
(:func:`~jaxbelt.rom.error_estimate.error_rom`) reads them.

The tracers are where the configuration's own sensors sit on the belt (``model.tracer_col``,
``tracer_xi``, …), not a property of the dynamics the reduced model learnt: configurations of one
mesh may place them differently, so a prediction observes its states with the predicted
configuration's operator, not the training runs'.
"""

from __future__ import annotations

import abc
import dataclasses
from typing import ClassVar, Iterator

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..state import initial_state
from ..timeloop import RunOptions
from .error_estimate import BasisTrajectory
from .snapshots import state_to_z, tracer_operator

CALIBRATION_RUNS = 3  # training runs the error estimate's safety factor is calibrated on


def observation(model) -> jax.Array:
    """``[C 0]`` (n_tr, 2N): the longitudinal tracer displacements (m) of a scaled first-order
    state of ``model`` (:func:`~jaxbelt.rom.snapshots.tracer_operator` at its tracers)."""
    C = tracer_operator(model)
    return jnp.concatenate([C, jnp.zeros_like(C)], axis=1)


class Prediction(eqx.Module):
    """A reduced model's prediction of ``n`` steps.

    **Fields:** ``tracer_u`` (n, n_tr) the longitudinal tracer displacements after each predicted
    step, m — after the step's transport where ``order`` is ``"post"``, before it (the solve's
    result) where ``"pre"``; ``basis`` (2N, b) orthonormal and ``coords`` (n + 1, b): the start
    and the predicted scaled first-order states ``basis @ coords[k]``; ``z_start`` (2N,) the full
    model's state the prediction starts from; ``order`` (static) whether the states are those
    after (``"post"``) or before (``"pre"``) each step's transport.
    """

    tracer_u: jax.Array
    basis: jax.Array
    coords: jax.Array
    z_start: jax.Array
    order: str = eqx.field(static=True, default="post")

    @property
    def trajectory(self) -> BasisTrajectory:
        """The predicted states as :func:`~jaxbelt.rom.error_estimate.error_rom` reads them."""
        return BasisTrajectory(self.basis, self.coords, self.z_start)

    def full_tracer_u(self, trajectory):
        """The full run's (:class:`~jaxbelt.Trajectory`) tracer displacements at the same point
        of each step as :attr:`tracer_u` (after the transport, or before it), m."""
        return trajectory.tracer_u if self.order == "post" else trajectory.tracer_u_solved

    @property
    def compared(self) -> str:
        """The name of the full run's field :meth:`full_tracer_u` reads."""
        return "tracer_u" if self.order == "post" else "tracer_u_solved"


@dataclasses.dataclass(frozen=True)
class Spectra:
    """What a plot of the fit shows: ``singular_values`` of the training snapshots, ``marked`` the
    number of modes to mark among them (``None``: the modes used), and for DMD-type methods the
    ``eigs`` with their ``eig_weights`` (the scaled mode norms, m)."""

    singular_values: np.ndarray
    marked: int | None = None
    eigs: np.ndarray | None = None
    eig_weights: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class TrainingRuns:
    """The full-order runs a reduction is fitted to.

    **Fields:** ``models`` the training configurations (same mesh; the nominal one first);
    ``runs`` the run settings of each (:class:`~jaxbelt.RunOptions`: the solver it uses, and the
    full-order steps and time step, which all runs share); ``own_solvers`` each configuration's own
    solver (the fully reduced POD step is linearised with the first one's); ``calibration_runs``
    how many of the runs (the first ones) the error estimate's safety factor is calibrated on.
    ``solvers``, ``n_steps`` and ``dt`` read the runs.
    """

    models: tuple
    runs: tuple[RunOptions, ...]
    own_solvers: tuple
    calibration_runs: int = CALIBRATION_RUNS

    def __post_init__(self):
        if len(self.runs) != len(self.models):
            raise ValueError(f"{len(self.runs)} run settings for {len(self.models)} training models")
        if len({(r.n_steps, r.dt) for r in self.runs}) > 1:
            raise ValueError("the training runs share their steps and time step")

    @property
    def solvers(self) -> tuple:
        """The solver of each training run."""
        return tuple(r.solver for r in self.runs)

    @property
    def n_steps(self) -> int:
        """Full-order steps per training run."""
        return int(self.runs[0].n_steps)

    @property
    def dt(self) -> float:
        """The time step, s."""
        return self.runs[0].dt

    def calibration_subset(self, items) -> list:
        """The first :attr:`calibration_runs` of ``items`` (one per training run)."""
        return list(items)[: self.calibration_runs]

    @property
    def observe(self):
        """:func:`observation` of the nominal configuration (the first)."""
        return observation(self.models[0])


class AbstractReducedModel(eqx.Module):
    """A reduced model fitted to training runs (:meth:`AbstractReduction.fit`)."""

    @abc.abstractmethod
    def predict(self, z0, mu, n_steps: int, observe=None) -> Prediction:
        """``n_steps`` steps from the scaled first-order state ``z0`` (2N,) of the configuration
        with parameters ``mu`` (2q,), its tracers observed by ``observe`` (n_tr, 2N), the predicted
        configuration's :func:`observation` (``None``: the nominal training configuration's, the
        same where the configurations share their tracer positions)."""

    @property
    @abc.abstractmethod
    def n_modes(self) -> int:
        """The reduced dimension."""

    def start(self, model, dt) -> tuple[int, jax.Array]:
        """``(step, z0)``: where a prediction of ``model`` starts — by default its initial state
        at step 0."""
        return 0, state_to_z(model, initial_state(model), dt)

    @abc.abstractmethod
    def spectra(self, z0) -> Spectra:
        """Singular values (and eigenvalues) of the fit, the mode weights from the start ``z0``."""

    @property
    def modes_discarded(self) -> int | None:
        """Modes the fit dropped as unstable (``None``: the method drops none)."""
        return None

    @property
    def training_starts_at_step(self) -> int | None:
        """The first step of the training trajectories where it is not step 0 (else ``None``)."""
        return None


class AbstractReduction(eqx.Module):
    """A model order reduction method and its settings: fits an :class:`AbstractReducedModel`.

    ``modes`` is the reduced dimension asked for (``None`` where the method chooses it); ``name``
    the method's name in reports (``jaxbelt reduce --method``)."""

    modes: eqx.AbstractVar[int | None]
    name: ClassVar[str]

    def __check_init__(self):
        if self.modes is not None and int(self.modes) < 1:
            raise ValueError(f"modes = {self.modes}: must be at least 1")

    @abc.abstractmethod
    def fit(self, training: TrainingRuns) -> AbstractReducedModel:
        """Run the training configurations and fit the reduced model to their snapshots."""

    @abc.abstractmethod
    def calibration_cases(self, fitted: AbstractReducedModel, training: TrainingRuns, half: int) -> Iterator:
        """:func:`~jaxbelt.rom.calibration.calibrate`'s cases: the same fit on the first ``half``
        training steps predicting training runs whose full-order states are known."""

    def check(self, n_steps: int, train_steps: int):
        """Raise ``ValueError`` where ``train_steps`` training steps cannot predict ``n_steps``."""
        if train_steps < 1:
            raise ValueError(f"n_steps = {n_steps}, train_steps = {train_steps}: too few steps to train on "
                             "(at least 1)")

    def check_training(self, model, train, solvers):
        """Raise ``ValueError`` where the training configurations ``train`` (with their own
        ``solvers``) cannot train this method to predict ``model``."""
        for i, m in enumerate(train):
            if m.n_unknowns != model.n_unknowns or m.kind != model.kind or m.n_tracers != model.n_tracers:
                raise ValueError(f"training model {i}: {m.kind} with N = {m.n_unknowns} and {m.n_tracers} tracers; "
                                 f"the predicted one has {model.kind}, N = {model.n_unknowns}, {model.n_tracers} "
                                 "tracers (training models need the same mesh)")
