"""The fully reduced POD step: solve *and* transport projected (model specification §5, the source's §8.1).

The source's POD-Galerkin reduced only the solve and handed the full state to the transport
step, so every reduced step still cost O(N) (§7.3, §8.1). Here both halves of the discrete step
are projected once, offline, and a reduced step costs O(r²) whatever the mesh.

**Structure used.** Write the scaled first-order state ``z = [x; Δt ẋ]`` (2N) and the
configuration parameters ``μ = [χ_static; ω]`` (2q): static misalignments and drive rates. With the shift transport rule and a uniform belt
the element masses never change, and then

* the Backward-Euler solve (eq. 3.43–3.46 with its constraint rows) is *affine* in ``(z, μ)``:
  ``z̃ = S z + T μ + c`` exactly in 1D; in 2D the lever arm of the tilts (``R_r`` depends on
  ``v``) and the exact finite static rotations make it weakly nonlinear, and it is linearised at
  the reference state of the training (the nominal configuration's initial state);
* the transport with an imposed shift ``s`` is affine in ``z̃`` and linear in ``s``:
  ``z⁺ = Z z̃ + s (G z̃ + H μ + h)``, where ``Z`` resets the roller rotations ``α_z`` and
  ``G`` is the upwind difference divided by the element length (with the roller-relative
  correction, ``R_r`` frozen at the reference), and ``s = cᵀ z̃`` is the mean longitudinal
  displacement — so the transport is *bilinear* in the state and projects exactly.

With an orthonormal POD basis ``V`` (2N, r) of training snapshots (before and after transport)
the reduced step is

$$ ξ̃ = A ξ + B μ + d,\\quad s = c_rᵀ ξ̃,\\quad ξ⁺ = Z_r ξ̃ + s (G_r ξ̃ + H_r μ + h_r) $$

with ``A = Vᵀ S V``, ``B = Vᵀ T``, ``Z_r = Vᵀ Z V``, … all assembled offline by Jacobian-vector
products of the full-order step along the basis (r + q products, no N × N matrix is formed).
This is the Galerkin projection of the *time-discrete* step map (not of the ODE, as
:class:`~jaxbelt.rom.pod.PODGalerkin` does); because ``μ`` enters explicitly, a basis trained on
several configurations predicts a new one without any full-order work beyond its initial state.
Tracers are read through ``C V`` (n_tr, r): full fields are never formed online.
"""

from __future__ import annotations

import functools
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from ..assembly import roller_R
from ..integrators import AbstractIntegrator, make_solver
from ..state import initial_state
from ..transport import transport_step_with_weights
from .error_estimate import BasisTrajectory
from .pod import pod_basis
from .reduced_model import AbstractReducedModel, AbstractReduction, Prediction, Spectra, TrainingRuns, observation
from .snapshots import collect_first_order, state_to_z, tracer_operator, z_to_state


def parameters(model):
    """The configuration parameters ``μ = [χ_static; ω]`` (2q,) a reduced model takes as input:
    static roller misalignments (m, rad) and drive rates (rad/s)."""
    return jnp.concatenate([model.chi_static, model.omega])


def parameters_outside_training(model, training_models, rel_tol: float = 1e-9) -> list[str]:
    """The components of ``model``'s :func:`parameters` outside the range its training
    configurations span, each as ``"static dx of 'idle' = 0.01 (trained over [0, 0.005])"``: a
    parametric or controlled DMD predicts there by extrapolation, which its interpolation weights
    (or input matrix) were not fitted for. A component no training configuration varies counts
    where the predicted value differs from theirs. ``rel_tol``: relative to the component's
    largest magnitude. **Returns:** the list (empty inside the range)."""
    P = np.stack([np.asarray(parameters(m)) for m in training_models])
    mu = np.asarray(parameters(model))
    lo, hi = P.min(axis=0), P.max(axis=0)
    tol = rel_tol * np.maximum(np.maximum(np.abs(lo), np.abs(hi)), np.abs(mu)) + 1e-300
    q, dofs = model.n_roller_dofs, model.dofs
    out = []
    for k in np.flatnonzero((mu < lo - tol) | (mu > hi + tol)):
        j = k % q
        what = "static" if k < q else "rate of"
        out.append(f"{what} {dofs[j % len(dofs)]} of {model.roller_names[j // len(dofs)]!r} = {mu[k]:.4g} "
                   f"(trained over [{lo[k]:.4g}, {hi[k]:.4g}])")
    return out


def with_parameters(model, mu):
    """``model`` with ``μ = [χ_static; ω]`` replaced (inverse of :func:`parameters`)."""
    q = model.n_roller_dofs
    return eqx.tree_at(lambda m: (m.chi_static, m.omega), model, (mu[:q], mu[q:]))


def solve_map(model, dt, solver: AbstractIntegrator | None = None, run_data=None):
    """``(z, μ) -> z̃``: one full-order solve of step ``dt`` (before transport) on scaled
    first-order states. ``run_data``: the solver's (``solver.init``), by default from
    ``model``'s initial state."""
    solver = make_solver() if solver is None else solver
    if run_data is None:
        run_data = solver.init(model, initial_state(model), dt)

    def f(z, mu):
        m = with_parameters(model, mu)
        return state_to_z(m, solver.step(m, z_to_state(m, z, dt), dt, run_data), dt)

    return f


def transport_map(model, R, dt):
    """``(z̃, μ, s) -> z⁺``: the shift transport step with imposed shift ``s`` and frozen ``R``
    on scaled first-order states of step ``dt``."""

    def f(z, mu, s):
        m = with_parameters(model, mu)
        st = z_to_state(m, z, dt)
        u, ud, chi, _, _ = transport_step_with_weights(m, st.u, st.u_dot, st.chi, st.m_e, s=s, R=R)
        return state_to_z(m, st.__class__(u=u, u_dot=ud, chi=chi, chi_dot=st.chi_dot, m_e=st.m_e, step=st.step), dt)

    return f


def shift_functional(model):
    """``c`` (2N,) with ``cᵀ z = mean`` longitudinal belt displacement (the shift, §3.5)."""
    n, b = model.n_xi, model.block
    c = np.zeros(2 * model.n_unknowns)
    cols = np.arange(n) * b
    idx = cols[:, None] + (np.arange(0, b, 2) if model.kind == "2d" else np.array([0]))[None, :]
    c[idx.reshape(-1)] = 1.0 / idx.size
    return jnp.asarray(c)


class ReducedTrajectory(eqx.Module):
    """What :meth:`ReducedStep.run` records, one row per step, as :class:`~jaxbelt.Trajectory`
    does for a full run. Units: m.

    **Fields:** ``xi`` (n, r) the reduced coordinates after each step's transport;
    ``tracer_u`` (n, n_tr) longitudinal tracer displacement after the transport; ``tracer_v``
    (n, n_tr) lateral (zero in 1D); ``tracer_u_solved`` (n, n_tr) longitudinal before the
    transport (the solve's result)."""

    xi: jax.Array
    tracer_u: jax.Array
    tracer_v: jax.Array
    tracer_u_solved: jax.Array


class ReducedStep(eqx.Module):
    """Fully reduced POD model (offline operators; see the module docstring). ``basis`` (2N, r) is
    kept only to lift and to reconstruct fields; the online loop touches r-sized arrays only.
    ``dt``: the time step it was projected at, s (its step is one full step of that size; it
    scales the velocity half of the states, :func:`~jaxbelt.rom.snapshots.state_to_z`);
    ``singular_values``: of the training snapshots, where it was fitted to them (else ``None``)."""

    basis: jax.Array
    A: jax.Array
    B: jax.Array
    d: jax.Array
    c: jax.Array
    Z: jax.Array
    G: jax.Array
    H: jax.Array
    h: jax.Array
    C_tracer: jax.Array  # (n_tr, r): longitudinal tracer displacement from ξ
    C_lateral: jax.Array  # (n_tr, r): lateral tracer displacement (zero in 1D)
    dt: jax.Array
    singular_values: jax.Array | None = None

    @property
    def n_modes(self) -> int:
        return self.A.shape[0]

    def project(self, model, state):
        """Reduced coordinates ``ξ = Vᵀ z`` of a full state."""
        return self.basis.T @ state_to_z(model, state, self.dt)

    def step(self, xi, mu):
        """One reduced step: ``(ξ̃ before transport, ξ⁺ after)``."""
        xt = self.A @ xi + self.B @ mu + self.d
        s = self.c @ xt
        return xt, self.Z @ xt + s * (self.G @ xt + self.H @ mu + self.h)

    def run(self, xi0, mu, n_steps: int) -> ReducedTrajectory:
        """``n_steps`` reduced steps from the coordinates ``xi0`` (r,) with the parameters ``mu``
        (:func:`parameters`): the :class:`ReducedTrajectory`."""

        def body(xi, _):
            xt, xn = self.step(xi, mu)
            return xn, (xn, self.C_tracer @ xn, self.C_lateral @ xn, self.C_tracer @ xt)

        _, (xis, tu, tv, tus) = lax.scan(body, xi0, None, length=n_steps)
        return ReducedTrajectory(xi=xis, tracer_u=tu, tracer_v=tv, tracer_u_solved=tus)

    def fields(self, xis):
        """Full scaled first-order states ``V ξ`` (n, 2N) — offline/diagnostic use only."""
        return xis @ self.basis.T

    def truncate(self, r: int) -> "ReducedStep":
        """The model of the first ``r`` modes. Every operator is a Galerkin projection linear in
        each basis column (``A = Vᵀ S V``, ``G = Vᵀ (∂transport) V``, …), so the rank-``r``
        operators are exactly the leading blocks of these: one offline projection serves every
        rank ≤ :attr:`n_modes` (no recompilation per rank)."""
        r = int(r)
        if not 1 <= r <= self.n_modes:
            raise ValueError(f"truncate: r = {r} outside 1 … {self.n_modes}")
        sq = lambda M: M[:r, :r]
        return ReducedStep(basis=self.basis[:, :r], A=sq(self.A), B=self.B[:r], d=self.d[:r], c=self.c[:r],
                           Z=sq(self.Z), G=sq(self.G), H=self.H[:r], h=self.h[:r],
                           C_tracer=self.C_tracer[:, :r], C_lateral=self.C_lateral[:, :r], dt=self.dt,
                           singular_values=self.singular_values)


def reduced_operators(model, V, dt, solver: AbstractIntegrator | None = None, ref_state=None, mu_ref=None,
                      singular_values=None) -> ReducedStep:
    """Project the full step of size ``dt`` (``solver``'s solve, default
    :func:`jaxbelt.make_solver`'s, then the shift transport) onto ``V`` (2N, r): the
    :class:`ReducedStep` of basis ``V`` (``singular_values`` stored with it).

    Linearisation point: ``ref_state`` (default: the initial state of ``model``) and
    ``mu_ref`` (default :func:`parameters` of ``model``). Costs r + q + 2 Jacobian-vector products.
    """
    solver = make_solver() if solver is None else solver
    if solver.transport != "shift":
        raise ValueError("the fully reduced step needs the 'shift' transport rule (masses constant)")
    ref_state = initial_state(model) if ref_state is None else ref_state
    mu_ref = parameters(model) if mu_ref is None else jnp.asarray(mu_ref)
    V = jnp.asarray(V)
    dt = jnp.asarray(dt, V.dtype)
    c = shift_functional(model)
    ops = _operators(model, solver, ref_state, mu_ref, V, c, dt)

    def lift(C):
        return jnp.concatenate([C, jnp.zeros_like(C)], axis=1) @ V

    C_lat = lift(tracer_operator(model, "z")) if model.kind == "2d" else jnp.zeros((model.n_tracers, V.shape[1]))
    return ReducedStep(basis=V, c=c @ V, C_tracer=lift(tracer_operator(model)), C_lateral=C_lat, dt=dt,
                       singular_values=singular_values, **ops)


@eqx.filter_jit
def _operators(model, solver, ref_state, mu_ref, V, c, dt):
    z_ref = state_to_z(model, ref_state, dt)
    solve = solve_map(model, dt, solver, solver.init(model, ref_state, dt))
    R = roller_R(model, ref_state.u)
    transport = transport_map(model, R, dt)

    z_sol, lin = jax.linearize(solve, z_ref, mu_ref)
    SV = jax.vmap(lambda v: lin(v, jnp.zeros_like(mu_ref)), in_axes=1, out_axes=1)(V)
    T = jax.vmap(lambda e: lin(jnp.zeros_like(z_ref), e), in_axes=1, out_axes=1)(jnp.eye(mu_ref.size))
    Sz = lin(z_ref, jnp.zeros_like(mu_ref))
    c_full = z_sol - Sz - T @ mu_ref

    # the transport is linear in s for a fixed upwind direction (the belt's running direction, the
    # sign of the nominal shift): the difference quotient at s1 is exact
    direction = jnp.where(jax.lax.stop_gradient(c @ z_sol) < 0, -1.0, 1.0)
    s1 = direction * 0.5 * jnp.min(model.ell)
    zero_mu, zero_z = jnp.zeros_like(mu_ref), jnp.zeros_like(z_ref)

    def diff(z, mu):
        return (transport(z, mu, s1) - transport(z, mu, 0.0)) / s1

    ZV = jax.vmap(lambda v: transport(v, zero_mu, 0.0), in_axes=1, out_axes=1)(V) - transport(zero_z, zero_mu, 0.0)[:, None]
    h_mu, lin_t = jax.linearize(lambda mu: diff(zero_z, mu), mu_ref)
    Hmu = jax.vmap(lin_t, in_axes=1, out_axes=1)(jnp.eye(mu_ref.size))
    GV = jax.vmap(lambda v: diff(v, mu_ref), in_axes=1, out_axes=1)(V) - h_mu[:, None]
    h0 = h_mu - Hmu @ mu_ref
    return dict(A=V.T @ SV, B=V.T @ T, d=V.T @ c_full, Z=V.T @ ZV, G=V.T @ GV, H=V.T @ Hmu, h=V.T @ h0)


def fit_reduced_pod(model, snapshots, dt, solver: AbstractIntegrator | None = None, ref_state=None,
                    mu_ref=None, **choice) -> ReducedStep:
    """Fully reduced POD model from scaled first-order snapshots (2N, m) — e.g. ``Z_pre`` and
    ``Z_post`` of :func:`~jaxbelt.rom.snapshots.collect_first_order`, of one configuration or
    several side by side, taken with time step ``dt`` (and ``solver``). ``choice``:
    ``n_modes=`` / ``energy_tol=`` / ``rule="source"`` as :func:`~jaxbelt.rom.pod.pod_basis`.
    ``model``: the configuration to linearise at (use the nominal one for multi-configuration
    training)."""
    V, s = pod_basis(jnp.asarray(snapshots), **choice)
    return reduced_operators(model, V, dt, solver, ref_state, mu_ref, singular_values=s)


def fit_reduced_pod_ranks(model, snapshots, ranks, dt, solver: AbstractIntegrator | None = None, ref_state=None,
                          mu_ref=None) -> dict:
    """``{r: ReducedStep}`` for every ``r`` in ``ranks`` from one SVD and one projection at the
    largest rank (:meth:`ReducedStep.truncate`): the offline cost of a rank study is that of its
    largest model, compiled once."""
    ranks = sorted({int(r) for r in ranks})
    top = fit_reduced_pod(model, snapshots, dt, solver, ref_state, mu_ref, n_modes=ranks[-1])
    return {r: top.truncate(r) for r in ranks}


@functools.partial(jax.jit, static_argnums=3)
def _run(step: ReducedStep, xi0, mu, n_steps: int) -> ReducedTrajectory:
    return step.run(xi0, mu, n_steps)


class ReducedPODModel(AbstractReducedModel):
    """The fully reduced POD step fitted by :class:`ReducedPOD`: ``step`` (:class:`ReducedStep`)
    and its training ``snapshots``, per run ``(Z_pre, Z_post)``
    (:func:`~jaxbelt.rom.snapshots.collect_first_order`)."""

    step: ReducedStep
    snapshots: tuple

    @property
    def n_modes(self) -> int:
        return self.step.n_modes

    def predict(self, z0, mu, n_steps: int, observe=None) -> Prediction:
        """The step linearised at the nominal configuration, run with the parameters ``mu``; the
        tracers observed by ``observe`` where given (the predicted configuration's tracer
        operator), else by the nominal configuration's (:attr:`ReducedStep.C_tracer`)."""
        step = self.step if observe is None else eqx.tree_at(lambda s: s.C_tracer, self.step, observe @ self.step.basis)
        xi0 = step.basis.T @ z0
        out = _run(step, xi0, mu, int(n_steps))
        return Prediction(tracer_u=out.tracer_u, basis=self.step.basis, coords=jnp.concatenate([xi0[None], out.xi]),
                          z_start=z0, order="post")

    def spectra(self, z0) -> Spectra:
        return Spectra(singular_values=np.asarray(self.step.singular_values))


class ReducedPOD(AbstractReduction):
    """The fully reduced POD step (module docstring) of ``modes`` modes, trained on the snapshots
    before and after transport of every training run and linearised at the first (nominal)
    configuration with its own solver; it predicts any configuration from its initial state."""

    modes: int = 20
    name: ClassVar[str] = "pod"

    def fit(self, training: TrainingRuns) -> ReducedPODModel:
        snaps = tuple(collect_first_order(m, training.runs[i])[1:] for i, m in enumerate(training.models))
        Z = jnp.concatenate([z for p in snaps for z in p], axis=1)
        step = fit_reduced_pod(training.models[0], Z, training.dt, training.own_solvers[0], n_modes=self.modes)
        return ReducedPODModel(step=step, snapshots=snaps)

    def calibration_cases(self, fitted: ReducedPODModel, training: TrainingRuns, half: int):
        m_train = int(training.n_steps)
        first_half = [Z for Zpre, Zpost in fitted.snapshots for Z in (Zpre[:, :half], Zpost[:, :half + 1])]
        cfit = fit_reduced_pod(training.models[0], jnp.concatenate(first_half, axis=1), training.dt,
                               training.own_solvers[0], n_modes=self.modes)
        for m, s, (_, Zpost) in training.calibration_subset(zip(training.models, training.solvers, fitted.snapshots)):
            C, N = tracer_operator(m), m.n_unknowns  # each run at its own tracers
            x0 = cfit.project(m, initial_state(m))
            o = eqx.tree_at(lambda s: s.C_tracer, cfit, observation(m) @ cfit.basis).run(x0, parameters(m), m_train)
            yield m, (C @ Zpost[:N, 1:]).T, o.tracer_u, BasisTrajectory(
                cfit.basis, jnp.concatenate([x0[None], o.xi]), Zpost[:, 0]), s

    def check_training(self, model, train, solvers):
        super().check_training(model, train, solvers)
        for i, s in enumerate(solvers):
            if s.transport != "shift":
                raise ValueError(f"pod needs the 'shift' transport rule; training model {i} uses {s.transport!r}")
