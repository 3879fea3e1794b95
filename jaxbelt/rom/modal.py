"""Modal decomposition of the eliminated ODE (§5.1.1, §6.2, eq. 5.5–5.7).

``K̂ φ = ω² M̂ φ`` on the dynamic unknowns (the algebraic ones are eliminated first: on the DAE
the singular mass matrix gives infinite frequencies, §6.2). ``M̂`` and ``K̂`` of the belt are
symmetric up to round-off; they are symmetrised, ``M̂ = L Lᵀ`` (Cholesky) and the symmetric
problem ``L⁻¹ K̂ L⁻ᵀ y = ω² y`` is solved, so the modes ``Φ = L⁻ᵀ Y`` are M-orthonormal.

Two orderings: by frequency, and the source's proposal of §6.2 that accounts for the forcing —
modes ranked by ``|φᵢᵀ F̂| / ωᵢ`` (large projection on the right-hand side and low frequency first).

:func:`fit_modal` makes a reduced integrator of the first ``r`` modes in either order: the
Galerkin projection of the eliminated ODE onto their span, stepped with Backward Euler — the
same :class:`~jaxbelt.rom.pod.PODGalerkin` step as POD, with the modes in place of the POD basis
(orthonormalised by a QR factorisation: the span is the modes', the coordinates orthonormal, as the
step's projection ``ξ = Vᵀ x`` requires). ``benchmarks/modal_vs_pod.py`` measures its error
against the number of modes beside POD.

**Not a reduction of** :func:`~jaxbelt.rom.reduce_and_compare`. The modal model is a full-order
integrator in modal coordinates, not a reduced model of the kind
:class:`~jaxbelt.rom.reduced_model.AbstractReduction` fits: every step it assembles and
eliminates the full system at the current state, recovers the algebraic unknowns from the
constraints and transports the full state — only the solve is projected — so a step costs what
a full step costs and :func:`jaxbelt.simulate` runs it like any solver. Its states are therefore
no coordinates in one fixed basis of scaled first-order states (the algebraic unknowns,
recovered from the constraints, and the transported state leave the span of the modes), the form a
:class:`~jaxbelt.rom.reduced_model.Prediction` and the error estimate read; and it is built from
one configuration's operators at one state, not fitted to training runs, so a configuration
predicted with it needs its own modes. The pipeline's projection method is the fully reduced POD
step (:class:`~jaxbelt.rom.ReducedPOD`), whose online step is ``r``-dimensional; the modal basis
is a question of which basis, compared with POD in the same integrator.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..integrators import eliminated_system
from ..state import initial_state
from .pod import PODGalerkin


def modal_basis(model, state, dt):
    """``(omega (N_f,), Phi (N_f, N_f), F_hat (N_f,))`` at ``state`` and time step ``dt`` (the
    forcing's), by ascending frequency."""
    dyn, alg = model.partition
    M_hat, K_hat, F_hat, _, _, p = eliminated_system(model, state, dt, dyn, alg)
    M = 0.5 * (M_hat + M_hat.T)
    K = 0.5 * (K_hat + K_hat.T)
    L = jnp.linalg.cholesky(M)
    Li = jnp.linalg.inv(L)
    w2, Y = jnp.linalg.eigh(Li @ K @ Li.T)
    Phi = Li.T @ Y
    # forcing of the ODE at this step: F̂ - K̂ (x + Δt ẋ) is what drives the modes
    force = F_hat - K_hat @ p[jnp.asarray(dyn)]
    return jnp.sqrt(jnp.clip(w2, 0.0)), Phi, force


def forcing_order(omega, Phi, force):
    """Indices ranking modes by ``|φᵀ F| / ω`` (descending), the ordering proposed in §6.2."""
    score = jnp.abs(Phi.T @ force) / jnp.maximum(omega, 1e-300)
    return jnp.argsort(-score)


def modal_order(omega, Phi, force, order: str):
    """Mode indices in the order ``"frequency"`` (ascending ω) or ``"forcing"`` (|φᵀF|/ω, §6.2)."""
    if order == "frequency":
        return jnp.arange(omega.shape[0])
    if order == "forcing":
        return forcing_order(omega, Phi, force)
    raise ValueError(f"order = {order!r}: one of 'frequency', 'forcing'")


def fit_modal(model, n_modes: int, dt, order: str = "forcing", state=None, transport: str = "shift") -> PODGalerkin:
    """Modal reduced integrator: the first ``n_modes`` modes of :func:`modal_basis` at ``state``
    (default: the initial state) and time step ``dt`` in ``order`` (``"forcing"``: the RHS-aware
    ordering of §6.2; ``"frequency"``), as a Galerkin-projection integrator (module docstring)
    followed by the ``transport`` rule."""
    state = initial_state(model) if state is None else state
    omega, Phi, force = modal_basis(model, state, dt)
    n = int(Phi.shape[1])
    if not 1 <= int(n_modes) <= n:
        raise ValueError(f"n_modes = {n_modes}: between 1 and the {n} dynamic unknowns")
    sel = modal_order(omega, Phi, force, order)[: int(n_modes)]
    V, _ = jnp.linalg.qr(Phi[:, sel])
    return PODGalerkin(V, transport=transport)
