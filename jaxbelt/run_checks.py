"""What a run is checked for: its inputs before it starts (the time step against the transport
step's CFL condition, a start state against the solver's kept factors) and a non-finite state
after it (the step, its time and which part). :func:`jaxbelt.simulate` calls them; each is
skipped for traced values, where the caller checks.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .integrators import AbstractIntegrator
from .mesh import cfl_advice
from .model import BeltModel
from .state import BeltState


def belt_speed(model: BeltModel) -> float:
    """The belt speed the drive rollers impose, m/s (concrete models only)."""
    v = np.einsum("nbq,q->nb", np.asarray(model.R), np.asarray(model.omega))
    return float(np.max(np.abs(v[:, 0::2] if model.kind == "2d" else v), initial=0.0))


def check_time_step(model: BeltModel, dt) -> None:
    """``ValueError`` unless ``dt`` is a positive finite number meeting the transport step's CFL
    condition ``V Δt < ℓ_min`` (the belt moves less than the shortest element per step); skipped
    for traced values."""
    if isinstance(dt, jax.core.Tracer) or any(isinstance(a, jax.core.Tracer) for a in (model.R, model.omega, model.ell)):
        return
    dt = float(np.asarray(dt))
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt = {dt}: must be a positive number of seconds")
    V, h = belt_speed(model), float(np.min(np.asarray(model.ell)))
    if V * dt >= h:
        raise ValueError(f"dt = {dt:g} s violates the CFL condition of the transport step (belt speed {V:g} m/s × dt "
                         f"= {V * dt * 1e3:.4g} mm >= smallest element {h * 1e3:.4g} mm); {cfl_advice(h, V)}")


def check_start_masses(model: BeltModel, solver: AbstractIntegrator, y0: BeltState | None) -> None:
    """``ValueError`` where ``solver`` keeps its factors at the model's element masses for the whole
    run (:class:`~jaxbelt.integrators.KeptInterior` under the shift transport, which never changes
    them) and the start state ``y0`` has other masses: every step would solve with the wrong
    matrix. Round-off is allowed (``10⁴ ε`` relative, at least ``10⁻⁶``: a state carried from
    another run or grid); skipped for traced values."""
    linear = getattr(solver, "linear_solver", None)
    if y0 is None or linear is None or isinstance(y0.m_e, jax.core.Tracer) \
            or isinstance(model.m_e0, jax.core.Tracer) \
            or not linear.keeps_model_masses(model, getattr(solver, "transport", "shift")):
        return
    m, m0 = np.asarray(y0.m_e), np.asarray(model.m_e0)
    rtol = max(1e-6, 1e4 * float(np.finfo(m0.dtype).eps))
    if m.shape != m0.shape or not np.allclose(m, m0, rtol=rtol, atol=0.0):
        worst = float(np.max(np.abs(m / m0 - 1.0))) if m.shape == m0.shape else float("nan")
        raise ValueError(f"y0's element masses differ from the model's (by up to {worst:.3g} relative) and "
                         f"{type(linear).__name__} keeps its factors at the model's for the whole run; "
                         "step it with a solver that factors every step (DirectBackwardEuler(Structured()))")


NONFINITE_CAUSES = {1: "belt displacement", 2: "belt velocity", 3: "roller state"}


class NonFiniteStateError(FloatingPointError):
    """The simulated state became NaN or infinite (the step, its time and which part)."""


def nonfinite_code(u, u_dot, chi, chi_dot):
    """0 if the state is finite, else the code (:data:`NONFINITE_CAUSES`) of its first bad part."""
    fin = lambda a: jnp.all(jnp.isfinite(a))  # noqa: E731
    return jnp.where(~fin(u), 1, jnp.where(~fin(u_dot), 2, jnp.where(~(fin(chi) & fin(chi_dot)), 3, 0))).astype(jnp.int8)


def first_nonfinite(traj):
    """``(k, t, cause)`` of the first recorded step of ``traj`` (a :class:`~jaxbelt.timeloop.Trajectory`)
    whose state is not finite, or ``None``."""
    code = np.asarray(traj.nonfinite)
    bad = np.flatnonzero(code)
    if bad.size == 0:
        return None
    k = int(bad[0])
    return k, float(np.asarray(traj.t)[k]), NONFINITE_CAUSES[int(code[k])]


def check_finite(traj, dt: float | None = None):
    """Raise :class:`NonFiniteStateError` naming the step, its time and the cause if the run's
    state (``traj``, a :class:`~jaxbelt.timeloop.Trajectory`) became NaN/inf; nothing otherwise. Skipped (returns) when ``traj`` holds tracers (inside
    ``jit``/``grad``/``vmap`` the check belongs to the caller)."""
    if isinstance(traj.nonfinite, jax.core.Tracer):
        return
    hit = first_nonfinite(traj)
    if hit is not None:
        k, t, cause = hit
        step = round(t / float(dt)) if dt is not None else k + 1
        raise NonFiniteStateError(f"the simulation diverged: non-finite {cause} at step {step} (t = {t:g} s); "
                                  "check the time step against the CFL limit, the transport weights and the scene")
