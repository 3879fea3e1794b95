"""When to trust a reduced model: an a-posteriori error indicator and a snapshot-count rule.

**Residual indicator.** A reduced model produces a sequence of (lifted) full states
``z_0, z_1, …``. The exact model would have produced ``F(z_k)`` from ``z_k`` (one full-order
step: solve + transport). The one-step residual ``δ_k = F(z_k) - z_{k+1}`` is computable at the
cost of one full step, needs no reference run, and is zero iff the reduced trajectory is a
full-order trajectory. Since the step is affine up to the weak transport bilinearity, the error
obeys ``e_{k+1} ≈ J e_k + δ_k`` with ``J`` the step's Jacobian; the Backward-Euler step of the
undamped belt is (marginally) non-expansive, so ``‖C e_K‖ ≲ Σ_{k<K} ‖C δ_k‖`` — the accumulated
tracer residual is an estimate of the tracer error that errs on the high side when errors do
not all add up in phase. The residuals are evaluated at every ``stride``-th step only (the sum
is scaled by ``stride``), so the check costs ``n / stride`` full steps.

This is an *indicator* with a safety margin, not a rigorous bound: a rigorous bound would need
``sup_k ‖J^k‖`` in the tracer norm, which the transport's interpolation makes slightly larger
than one. ``tests/test_rom_indicator.py`` checks that it ranks models as their true errors do and
that it exceeds the true error on the cases there; ``benchmarks/rom_1d.py`` reports both.

**Snapshot rule** (the source chose the number of snapshots by eye, §8.1):
:func:`snapshot_count` grows the training window in chunks, refits after each, and stops when the
model fitted on everything *before* the newest chunk predicts that chunk within
``safety × tol`` — the model has stopped learning anything new from more full-order steps.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..integrators import resolve_integrator
from ..state import initial_state
from ..timeloop import make_step
from .metrics import rmse
from .snapshots import collect_first_order, state_to_z, tracer_operator, z_to_state


def full_step_map(model, integrator=None, order: str = "post"):
    """``z -> F(z)``: one full-order step on scaled first-order states. ``order="post"``: states
    after transport (solve, then transport); ``"pre"``: states before transport (transport, then
    solve), as for DMD on pre-transport snapshots."""
    step = make_step(model, resolve_integrator(integrator, model), record_solved=True)

    def post(z):
        return state_to_z(model, step(z_to_state(model, z))[0])

    def pre(z):
        from ..transport import transport_step

        st = z_to_state(model, z)
        u, ud, chi, m_e = transport_step(model, st.u, st.u_dot, st.chi, st.m_e)
        moved = st.__class__(u=u, u_dot=ud, chi=chi, chi_dot=st.chi_dot, m_e=m_e, step=st.step)
        _, rec = step(moved)
        return jnp.concatenate([rec["x_solved"], model.dt * rec["v_solved"]])

    if order not in ("post", "pre"):
        raise ValueError("order must be 'post' or 'pre'")
    return post if order == "post" else pre


def residual_indicator(model, states, stride: int = 10, integrator=None, order: str = "post"):
    """Residual-based error indicator of a reduced trajectory.

    **Arguments:** ``states`` (n+1, 2N): lifted scaled first-order states ``z_0 … z_n`` of the
    reduced model (``ReducedStep.fields``, ``DMDModel.predict``, …); ``stride``: evaluate every
    ``stride``-th step; ``order``: see :func:`full_step_map`.

    **Returns:** ``dict(step (k,), residual_mm (k,), estimate_mm (k,))``: the rms over tracers of
    ``C δ_k`` in mm at the sampled steps, and the accumulated estimate of the tracer error
    ``Σ stride·|C δ|`` up to each sampled step (mm).
    """
    states = jnp.asarray(states)
    F = jax.jit(jax.vmap(full_step_map(model, integrator, order)))
    idx = np.arange(0, states.shape[0] - 1, stride)
    C = tracer_operator(model)
    N = model.n_unknowns
    delta = F(states[idx]) - states[idx + 1]
    res = jnp.sqrt(jnp.mean((delta[:, :N] @ C.T) ** 2, axis=1)) * 1e3
    return dict(step=idx, residual_mm=res, estimate_mm=jnp.cumsum(res) * stride)


def snapshot_count(model, fit_predict, tol_mm: float = 0.02, chunk: int = 50, safety: float = 0.1,
                   max_steps: int = 2000, min_chunks: int = 2, integrator=None):
    """Number of full-order steps worth training on, decided from the data.

    Runs the full model ``chunk`` steps at a time. After each chunk ``k ≥ min_chunks`` it calls
    ``fit_predict(Z_train, n) -> tracer_u (n, n_tr)`` with the post-transport snapshots up to
    the previous chunk (2N, m) and compares the prediction of the newest ``chunk`` steps with the
    full model's tracers. Stops at the first chunk predicted within ``safety × tol_mm``.

    **Returns:** ``dict(n_steps, converged, history=[(m, rmse_mm), …], Z)``: the chosen count,
    whether the rule fired before ``max_steps``, the validation errors and the snapshots.
    """
    integrator = resolve_integrator(integrator, model)
    C = tracer_operator(model)
    N = model.n_unknowns
    state = initial_state(model)
    Z = None
    history = []
    while True:
        state, _, Zc = collect_first_order(model, chunk, integrator, state)
        Zc = Zc if Z is None else Zc[:, 1:]  # the start state is the previous chunk's end
        if Z is not None and Z.shape[1] >= min_chunks * chunk:
            truth = (C @ Zc[:N]).T
            err = float(rmse(truth, fit_predict(Z, Zc.shape[1]))) * 1e3
            history.append((int(Z.shape[1] - 1), err))
            if err < safety * tol_mm:
                return dict(n_steps=int(Z.shape[1] - 1), converged=True, history=history, Z=Z)
        Z = Zc if Z is None else jnp.concatenate([Z, Zc], axis=1)
        if Z.shape[1] - 1 >= max_steps:
            return dict(n_steps=int(Z.shape[1] - 1), converged=False, history=history, Z=Z)
