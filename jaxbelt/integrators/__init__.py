"""Time integrators and linear solvers for the belt DAE (§3.4), as objects.

An integrator (:class:`AbstractIntegrator`: ``init``, ``step``) is one Backward-Euler step and
its transport rule; the direct one takes a linear solver (:mod:`jaxbelt.integrators.linear`:
``init``, ``compute``, ``transpose``). :func:`make_solver` builds them from the names of
:mod:`jaxbelt.registry`, the ones a scene file and the command line use.
"""

from ..registry import DEFAULT_INTEGRATOR, DEFAULT_LINEAR_SOLVER, DEFAULT_TRANSPORT, INTEGRATORS, LINEAR_SOLVERS
from ._base import AbstractIntegrator as AbstractIntegrator
from .direct import DirectBackwardEuler as DirectBackwardEuler
from .eliminated import EliminatedBackwardEuler as EliminatedBackwardEuler
from .eliminated import eliminated_system as eliminated_system
from .linear import AbstractLinearSolver as AbstractLinearSolver
from .linear import CyclicReduction as CyclicReduction
from .linear import Dense as Dense
from .linear import KeptInterior as KeptInterior
from .linear import Reuse as Reuse
from .linear import StepOperator as StepOperator
from .linear import Structured as Structured
from .naive import NaiveBackwardEuler as NaiveBackwardEuler

_INTEGRATOR_CLASSES = {"direct": DirectBackwardEuler, "naive": NaiveBackwardEuler,
                       "eliminated": EliminatedBackwardEuler}
_LINEAR_SOLVER_CLASSES = {"kept-interior": KeptInterior, "structured": Structured,
                          "cyclic-reduction": CyclicReduction, "reuse": Reuse, "dense": Dense}
assert set(_INTEGRATOR_CLASSES) == set(INTEGRATORS) and set(_LINEAR_SOLVER_CLASSES) == set(LINEAR_SOLVERS)


def make_linear_solver(name: str = DEFAULT_LINEAR_SOLVER) -> AbstractLinearSolver:
    """The linear solver of a registry name (:data:`jaxbelt.registry.LINEAR_SOLVERS`)."""
    if name not in _LINEAR_SOLVER_CLASSES:
        raise ValueError(f"unknown linear solver {name!r} (one of {', '.join(LINEAR_SOLVERS)})")
    return _LINEAR_SOLVER_CLASSES[name]()


def make_solver(integrator: str = DEFAULT_INTEGRATOR, linear_solver: str | AbstractLinearSolver | None = None,
                transport: str = DEFAULT_TRANSPORT) -> AbstractIntegrator:
    """The integrator of registry names (what a scene's ``[solver]`` table and ``--solver`` say).

    **Arguments:** ``integrator``: ``"direct"``, ``"naive"`` or ``"eliminated"``;
    ``linear_solver``: for the direct integrator, a name of :data:`jaxbelt.registry.LINEAR_SOLVERS`
    or a solver object (default ``"kept-interior"``); ``transport``: ``"shift"`` or ``"source"``.
    """
    if integrator not in _INTEGRATOR_CLASSES:
        raise ValueError(f"unknown integrator {integrator!r} (one of {', '.join(INTEGRATORS)})")
    if integrator != "direct":
        return _INTEGRATOR_CLASSES[integrator](transport=transport)
    if not isinstance(linear_solver, AbstractLinearSolver):
        linear_solver = make_linear_solver(linear_solver or DEFAULT_LINEAR_SOLVER)
    return DirectBackwardEuler(linear_solver, transport=transport)


def solver_name(solver: AbstractIntegrator) -> str:
    """``"direct/kept-interior"``-style name of an integrator (for reports)."""
    name = {cls: k for k, cls in _INTEGRATOR_CLASSES.items()}.get(type(solver), type(solver).__name__)
    if isinstance(solver, DirectBackwardEuler):
        ls = {cls: k for k, cls in _LINEAR_SOLVER_CLASSES.items()}.get(type(solver.linear_solver),
                                                                        type(solver.linear_solver).__name__)
        return f"{name}/{ls}"
    return name
