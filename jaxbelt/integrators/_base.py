"""Interchangeable time integrators for the belt DAE (§3.4)."""

from __future__ import annotations

import abc

import equinox as eqx

from ..model import BeltModel
from ..state import BeltState


class AbstractIntegrator(eqx.Module):
    """One Backward-Euler step of ``K x + M ẍ = F`` from a transported state.

    ``solve_step`` returns the *pre-transport* state ``(x̃, x̃̇)`` at ``t + Δt`` (masses and
    step counter untouched); :func:`jaxbelt.simulate` then applies the transport step.
    """

    @abc.abstractmethod
    def solve_step(self, model: BeltModel, state: BeltState) -> BeltState:
        """Advance ``state`` by one step of size ``model.dt`` (before transport)."""

    def prepare(self, model: BeltModel) -> "AbstractIntegrator":
        """Per-run set-up, called by the time loop once before its scan (inside ``jit``): the
        integrator to use for ``model``'s steps. Default: ``self``."""
        return self
