"""Time integrators: naive 3N system, direct Backward Euler (default), eliminated ODE (§3.4)."""

from ._base import AbstractIntegrator as AbstractIntegrator
from .direct import DirectBackwardEuler as DirectBackwardEuler
from .eliminated import EliminatedBackwardEuler as EliminatedBackwardEuler
from .eliminated import algebraic_partition as algebraic_partition
from .eliminated import eliminated_system as eliminated_system
from .naive import NaiveBackwardEuler as NaiveBackwardEuler
from .reuse import ReusedFactorisationBackwardEuler as ReusedFactorisationBackwardEuler

INTEGRATORS = ("naive", "direct", "eliminated")


def make_integrator(name: str, model, linear_solver: str | None = None) -> AbstractIntegrator:
    """Integrator by name: ``"naive"``, ``"direct"`` or ``"eliminated"``; the direct one with the
    linear solver ``"structured"`` (exact), ``"dense"`` (reference) or ``"reuse"`` (frozen
    factorisation + iterative refinement)."""
    if name == "direct":
        ls = linear_solver or model.linear_solver
        if ls == "reuse":
            return ReusedFactorisationBackwardEuler.for_model(model)
        return DirectBackwardEuler.for_model(model, ls)
    if name == "naive":
        return NaiveBackwardEuler()
    if name == "eliminated":
        return EliminatedBackwardEuler.for_model(model)
    raise ValueError(f"unknown integrator {name!r} (one of {', '.join(INTEGRATORS)})")


def resolve_integrator(integrator, model) -> AbstractIntegrator:
    """``integrator`` itself, or the one it names, or (``None``) the scene's choice."""
    if integrator is None or isinstance(integrator, str):
        return make_integrator(integrator or model.integrator, model)
    return integrator
