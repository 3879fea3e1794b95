"""The time-stepping state and the consistent initial condition (§3.4 'Initial conditions')."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .assembly import dae_matrices, static_rhs
from .control import ControllerState, initial_controller_state
from .linalg import bordered_solve
from .model import BeltModel


class BeltState(eqx.Module):
    """State between two steps (after transport). Shapes: ``u``, ``u_dot`` (n_xi, b) belt
    displacement (m) and velocity (m/s) per node column; ``chi``, ``chi_dot`` (q,) roller DOFs
    (m, rad) and rates; ``m_e`` (n_xi,) element masses (kg); ``step`` number of steps taken;
    ``control`` the steering loops' controller state (:class:`jaxbelt.control.ControllerState`),
    ``None`` for a machine without them."""

    u: jax.Array
    u_dot: jax.Array
    chi: jax.Array
    chi_dot: jax.Array
    m_e: jax.Array
    step: jax.Array
    control: ControllerState | None = None


@eqx.filter_jit
def initial_state(model: BeltModel) -> BeltState:
    """Static equilibrium ``K x = F`` on the misaligned rollers, with zero velocity except the
    drive rollers (``α̇_z = ω``) and the belt on them (``u̇ = R_r χ̇ = V``), as model specification §2."""
    K, _ = dae_matrices(model, model.m_e0)
    u, chi = bordered_solve(K, *static_rhs(model))
    chi_dot = model.omega
    u_dot = jnp.einsum("nbq,q->nb", model.R, chi_dot)  # non-zero only on the drive rollers' nodes
    control = None if model.control is None else initial_controller_state(model.control, u)
    return BeltState(u=u, u_dot=u_dot, chi=chi, chi_dot=chi_dot, m_e=model.m_e0,
                     step=jnp.zeros((), jnp.int32), control=control)
