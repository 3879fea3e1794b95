"""The time-stepping state and the consistent initial condition (§3.4 'Initial conditions')."""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .assembly import dae_matrices, static_rhs
from .control import ControllerState, initial_controller_state
from .infra.programs import stored_jit
from .linalg import bordered_solve
from .mesh import Mesh
from .model import BeltModel
from .registry import START_RULES
from .scene import Scene


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
      torsional mode on the belt's spans (on ``two-roller-1d`` about 96 Hz, the roller's speed
      between 0 and twice its mean). The model has no material damping, so that swing is
      undamped physics; Backward Euler multiplies a mode of angular frequency ``ω`` by
      ``1/√(1 + ω²Δt²)`` per step, so how long the swing lasts depends on ``Δt`` — gone within a
      few steps at the scenes' ``Δt``, alive for seconds at ``Δt/1000`` (``docs/speed.md``).
    - ``"running"``: the machine already running at the drive speed — every belt node moving
      along the path at ``V`` (``u̇_x = V``) and every idle roller turning with it
      (``α̇_z`` such that its nodes' ``R_r χ̇ = V``, least squares over its wrap) — consistent with
      no slip, so no swing is started and runs at any ``Δt`` agree to their discretisation error.
    """
    if start not in START_RULES:
        raise ValueError(f"start = {start!r}: one of {', '.join(START_RULES)}")
    return _initial_state(model, start == "running")


SWING_WARN_FRACTION = 1e-4  # the start-up swing's amplitude left at a run's end that is worth a warning


def start_swing(scene: Scene, mesh: Mesh, dt: float, n_steps: int):
    """The torsional swing a start from rest sets the idle (and tension) rollers on, and how much
    of it Backward Euler leaves after ``n_steps`` steps of ``dt``: one ``(roller name, frequency
    Hz, fraction of the start amplitude left)`` per torsional mode, named by the roller that swings
    most in it.

    The rollers' inertias ``I = ½ m_r r²`` (model specification §2) turn on the axial stiffness of
    the spans between them, ``EA/L`` each (``A`` the belt's cross-section), the drive held at its
    speed: the modes solve ``K φ = ω² I φ`` with the span energy ``½ Σ EA/L (r_b θ_b − r_a θ_a)²``
    (the belt's own mass left out: on ``two-roller-1d`` 96.0 Hz against 95.5 Hz measured).
    Backward Euler multiplies an undamped mode by ``1/√(1 + ω²Δt²)`` per step; the model has no
    material damping, so what it leaves is in the answer."""
    b = scene.belt
    EA = b.youngs_modulus * b.width * b.thickness
    free = [j for j, r in enumerate(scene.rollers) if r.role != "drive"]
    if not free:
        return []
    p = len(scene.rollers)
    K = np.zeros((p, p))
    for s in mesh.path.segments:
        if s.kind != "free":
            continue
        a, c = s.index, (s.index + 1) % p
        g = np.zeros(p)
        g[a] -= scene.rollers[a].radius
        g[c] += scene.rollers[c].radius
        K += EA / s.length * np.outer(g, g)
    K = K[np.ix_(free, free)]
    inertia = np.array([0.5 * scene.rollers[j].mass * scene.rollers[j].radius ** 2 for j in free])
    scale = 1.0 / np.sqrt(inertia)
    w2, phi = np.linalg.eigh(scale[:, None] * K * scale[None, :])
    out = []
    for k in range(len(free)):
        omega = float(np.sqrt(max(w2[k], 0.0)))
        left = float((1.0 + (omega * dt) ** 2) ** (-0.5 * n_steps))
        name = scene.rollers[free[int(np.argmax(np.abs(phi[:, k] * scale)))]].name
        out.append((name, omega / (2 * np.pi), left))
    return out

@stored_jit
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


def _interpolation_matrix(x_from, x_to, period=None):
    """``W`` (n_to, n_from): linear interpolation from the points ``x_from`` to ``x_to`` (periodic
    with ``period``), ``f(x_to) = W f(x_from)``."""
    order = np.argsort(x_from)
    W = np.stack([np.interp(x_to, x_from[order], e, period=period) for e in np.eye(len(x_from))], axis=1)
    return W[:, np.argsort(order)]


def prolongate(state: BeltState, coarse: BeltModel, fine: BeltModel) -> BeltState:
    """``state`` of ``coarse`` carried onto ``fine``'s grid — the same machine meshed otherwise —
    as the start of a steady solve there: belt displacements and velocities interpolated linearly
    along the loop (periodic, at the node positions ``x``) and across the width (``z0``), element
    masses as their relative deviation from the rest mass at the element centres, the roller and
    controller states copied. Not a solution on the finer grid: Newton then removes the grid's
    difference, a small residual next to a start from the static equilibrium (host-side, numpy)."""
    L = float(np.sum(np.asarray(coarse.ell)))
    xc, xf = np.asarray(coarse.x), np.asarray(fine.x)
    along = _interpolation_matrix(xc, xf, L)
    mid_c, mid_f = (xc + 0.5 * np.asarray(coarse.ell)) % L, (xf + 0.5 * np.asarray(fine.ell)) % L
    along_e = _interpolation_matrix(mid_c, mid_f, L)
    if coarse.kind == "2d":
        zc, zf = np.asarray(coarse.z0), np.asarray(fine.z0)
        across = _interpolation_matrix(zc, zf)
        across_e = _interpolation_matrix(0.5 * (zc[:-1] + zc[1:]), 0.5 * (zf[:-1] + zf[1:]))

    def nodal(a):
        a = np.asarray(a)
        if coarse.kind == "1d":
            return along @ a
        a = a.reshape(a.shape[0], coarse.n_eta, 2)
        return np.einsum("Ii,Jj,ijc->IJc", along, across, a).reshape(len(xf), -1)

    rel = np.asarray(state.m_e) / np.asarray(coarse.m_e0) - 1.0
    rel = along_e @ rel if coarse.kind == "1d" else along_e @ rel @ across_e.T
    dtype = fine.ell.dtype
    return dataclasses.replace(
        state, u=jnp.asarray(nodal(state.u), dtype), u_dot=jnp.asarray(nodal(state.u_dot), dtype),
        m_e=jnp.asarray((1.0 + rel) * np.asarray(fine.m_e0), dtype), step=jnp.zeros((), jnp.int32))
