"""The time-stepping state and the consistent initial condition (§3.4 'Initial conditions')."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .assembly import dae_matrices, static_rhs
from .control import ControllerState, initial_controller_state
from .linalg import bordered_solve
from .model import BeltModel
from .registry import START_RULES


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


def initial_state(model: BeltModel, start: str = "rest") -> BeltState:
    """Static equilibrium ``K x = F`` on the misaligned rollers, with velocities by ``start``:

    - ``"rest"`` (model specification §2): zero velocity except the drive rollers (``α̇_z = ω``)
      and the belt on them (``u̇ = R_r χ̇ = V``). The belt on the free spans and the idle rollers
      start from rest: an impulsive start, which sets every idle roller swinging in its
      torsional mode on the belt's spans (on ``two-roller-1d`` about 100 Hz, the roller's speed
      between 0 and twice its mean). The model has no material damping, so that swing is
      undamped physics; Backward Euler damps a mode of frequency ``ω`` by about ``ω²Δt/2`` per
      unit time, so how long the swing lasts depends on ``Δt`` — gone within 0.1 s at the
      scenes' ``Δt``, alive for seconds at ``Δt/100`` (``docs/speed.md``).
    - ``"running"``: the machine already running at the drive speed — every belt node moving
      along the path at ``V`` (``u̇_x = V``) and every idle roller turning with it
      (``α̇_z`` such that its nodes' ``R_r χ̇ = V``, least squares over its wrap) — consistent with
      no slip, so no swing is started and runs at any ``Δt`` agree to their discretisation error.
    """
    if start not in START_RULES:
        raise ValueError(f"start = {start!r}: one of {', '.join(START_RULES)}")
    return _initial_state(model, start == "running")


@eqx.filter_jit
def _initial_state(model: BeltModel, running: bool) -> BeltState:
    K, _ = dae_matrices(model, model.m_e0)
    u, chi = bordered_solve(K, *static_rhs(model))
    chi_dot = model.omega
    u_dot = jnp.einsum("nbq,q->nb", model.R, chi_dot)  # non-zero only on the drive rollers' nodes
    if running:
        x_mask = jnp.ones(u.shape[1]) if model.kind == "1d" else jnp.tile(jnp.array([1.0, 0.0]), u.shape[1] // 2)
        vx = (u_dot * x_mask).reshape(-1)
        speed = vx[jnp.argmax(jnp.abs(vx))]  # V with the sign of the belt's forward motion
        Rx = model.R * x_mask[None, :, None]  # (n, b, q): the x velocity per unit roller rate
        free_az = model.is_az & (model.omega == 0)  # idle rollers' rotations (not driven)
        rate = speed * jnp.sum(Rx, axis=(0, 1)) / jnp.maximum(jnp.sum(Rx**2, axis=(0, 1)), 1e-300)
        chi_dot = jnp.where(free_az & model.dynamic, rate, chi_dot)
        u_dot = speed * x_mask * jnp.ones_like(u_dot)
    control = None if model.control is None else initial_controller_state(model.control, u)
    return BeltState(u=u, u_dot=u_dot, chi=chi, chi_dot=chi_dot, m_e=model.m_e0,
                     step=jnp.zeros((), jnp.int32), control=control)
