"""Interchangeable time integrators for the belt DAE (§3.4)."""

from __future__ import annotations

import abc
from typing import Any

import equinox as eqx

from ..model import BeltModel
from ..registry import DEFAULT_TRANSPORT, TRANSPORT_RULES
from ..state import BeltState


class AbstractIntegrator(eqx.Module):
    """One Backward-Euler step of ``K x + M ẍ = F`` from a transported state, and the transport
    rule that puts its result back on the grid (:mod:`jaxbelt.transport`).

    :func:`jaxbelt.simulate` calls :meth:`init` once per run, inside the compiled program, and
    :meth:`step` every step; :meth:`step` returns the *pre-transport* state ``(x̃, x̃̇)`` at
    ``t + Δt`` (masses and step counter untouched), and the time loop then applies the transport
    step with :attr:`transport`.

    ``transport``: ``"shift"`` or ``"source"`` (:data:`jaxbelt.registry.TRANSPORT_RULES`).
    """

    transport: str = eqx.field(static=True, default=DEFAULT_TRANSPORT, kw_only=True)

    def __check_init__(self):
        if self.transport not in TRANSPORT_RULES:
            raise ValueError(f"transport = {self.transport!r}: unknown rule (one of {', '.join(TRANSPORT_RULES)})")

    def init(self, model: BeltModel, state: BeltState, dt) -> Any:
        """Data kept for the run (factors, stencils), from the model, the start state and the time
        step ``dt`` (s, traced). Default: ``None``."""
        return None

    @abc.abstractmethod
    def step(self, model: BeltModel, state: BeltState, dt, run_data) -> BeltState:
        """Advance ``state`` by one step of size ``dt`` (before transport); ``run_data`` is what
        :meth:`init` returned."""
