"""Shared test helpers: scenes and their run options, finite differences, random structured matrices."""

import contextlib
import copy
import tomllib
from importlib import resources
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.assembly import dae_matrices, dae_rhs
from jaxbelt.linalg import BorderedBlockCyclic, join

REPO = Path(__file__).resolve().parent.parent  # the repository's root

COMPILE_EVENT = "/jax/core/compile/backend_compile_duration"  # an XLA compile, or a load from the cache
TRACE_EVENT = "/jax/core/compile/jaxpr_trace_duration"  # a function traced to a jaxpr


@contextlib.contextmanager
def counting_compiles():
    """The names of the compile and trace events JAX reports inside the block (a list)."""
    events = []

    def listener(event, duration, **kwargs):
        if event in (COMPILE_EVENT, TRACE_EVENT):
            events.append(event)

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        yield events
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)


# A box of misalignments on the two-roller machine in the sweep's --dist format, for the reduced
# models trained over a box (reduce --train-ranges): the drive ±12 mm and the idle roller ±6 mm
# along x (a normal law, 3σ = 6 mm).
TWO_ROLLER_BOX = """
[roller."drive"]
translation_mm = {dist = "uniform", half_width = [12.0, 0.0, 0.0]}
[roller."idle"]
translation_mm = {dist = "normal", sigma = [2.0, 0.0, 0.0]}
"""


# A coarse 2D belt on the two-roller machine (28 columns x 3 rows), shared by the test modules that
# need a tiny 2D scene as TOML text (same mesh: their compiled programs are shared too); each adds
# its own [time], [output] and [variant] sections.
COARSE_2D_TWO_ROLLER = """\
extends = "two-roller-1d"
[model]
kind = "2d"
[mesh]
n_eta = 3
roller_elements = [6, 6]
free_elements = [8, 8]
"""

# A coarse 1D string on the two-roller machine (22 elements, 20 steps of 10 ms), as TOML text: a
# model that builds quickly for the command-line tests; a module may add its own sections.
COARSE_1D_TWO_ROLLER = """\
extends = "two-roller-1d"
[mesh]
roller_elements = [5, 5]
free_elements = [6, 6]
[time]
dt_s = 0.01
t_end_s = 0.2
"""


def builtin_dict(name="two-roller-1d") -> dict:
    return tomllib.loads((resources.files("jaxbelt") / "scenes" / f"{name}.toml").read_text())


def scene_with(mutate, name="two-roller-1d"):
    """Build a scene from a built-in one after ``mutate(d)`` edits its TOML dictionary."""
    d = copy.deepcopy(builtin_dict(name))
    mutate(d)
    return jb.scene_from_dict(d)


def span_strains(model, mesh, u):
    """Strain of every element of each free span (list of arrays), from node displacements."""
    u = np.asarray(u)[:, 0]
    ell = np.asarray(model.ell)
    out = []
    n = len(u)
    for k, seg in enumerate(mesh.path.segments):
        if seg.kind != "free":
            continue
        first = mesh.segment_starts[k] - 1  # exit contact line of the upstream roller
        ne = mesh.free_elements[seg.index]
        ids = np.arange(first, first + ne + 1) % n
        out.append(np.diff(u[ids]) / ell[ids[:-1]])
    return out


def central_difference(f, x, h):
    return (f(x + h) - f(x - h)) / (2 * h)


def whole_chunks(n_steps: int) -> int:
    """The smallest run length ``≥ n_steps`` that is a whole number of ``⌈√n⌉``-step checkpoint
    chunks (``jaxbelt.loop_plan.default_checkpoint_chunk``): its loop has no padded slots that
    branch around the step (``jaxbelt.loop_plan.loop_plan``; the step is compiled once either way)."""
    from jaxbelt.loop_plan import default_checkpoint_chunk

    n = n_steps
    while n > default_checkpoint_chunk(n) and n % default_checkpoint_chunk(n):
        n += 1
    return n


def load(source, **changes):
    """``(model, options)`` of a scene (built-in name, path or :class:`jaxbelt.Scene`): its model and
    its own run settings (:class:`jaxbelt.RunOptions`), ``changes`` applied to the latter."""
    scene = jb.load_scene(source) if isinstance(source, str) else source
    return jb.build_model(scene), jb.RunOptions.from_scene(scene).replace(**changes)


def coarse(name, n_eta=3):
    """``(model, options)`` of a built-in scene on a coarser grid."""
    return load(scene_with(lambda d: d.setdefault("mesh", {}).update(n_eta=n_eta), name))


def scene_fixtures(source):
    """Module-scoped fixtures ``loaded`` (``(model, options)`` of :func:`load`), ``model`` and
    ``dt`` for a test module: ``loaded, model, dt = scene_fixtures(name)``. ``source``: what
    :func:`load` takes, or a function returning it (built when the first test needs it)."""

    @pytest.fixture(scope="module")
    def loaded():
        return load(source() if callable(source) else source)

    @pytest.fixture(scope="module")
    def model(loaded):
        return loaded[0]

    @pytest.fixture(scope="module")
    def dt(loaded):
        return loaded[1].dt

    return loaded, model, dt


def trajectory(model, options, **changes):
    """The :class:`jaxbelt.Trajectory` of ``jb.simulate(model, **options)``, ``changes`` applied."""
    return jb.simulate(model, **options.replace(**changes))[1]


def simulate_optimised(model, options, n_steps=None):
    """The trajectory of ``jb.simulate(model, **options)`` from a program compiled at XLA's
    optimisation level 1, for the few long 2D runs (over a thousand steps) whose running time
    outweighs their compile: the suite compiles at -O0 (tests/conftest.py), and a -O0 program runs
    a 2D step ~4× slower, for ~2 s less compile. Checks the run for non-finite states as
    ``jb.simulate`` does."""
    n = options.n_steps if n_steps is None else n_steps
    tr = _optimised_run(model, options.solver, options.dt, n, options.saveat)
    jb.check_finite(tr, options.dt)
    return tr


def _run(model, solver, dt, n_steps, saveat):
    return jb.simulate(model, solver, n_steps=n_steps, dt=dt, saveat=saveat, check=False)[1]


_optimised_run = jax.jit(_run, static_argnums=(3, 4), compiler_options={"xla_backend_optimization_level": 1})


def solve_step(model, integrator, state, dt):
    """One step's solve from ``state`` before transport (``integrator.step`` with the run data
    ``integrator.init`` computes from ``state``), as one compiled program (op by op: ~40 compiles)."""
    return _solve_step(model, integrator, state, jax.numpy.asarray(dt, dtype=model.ell.dtype))


@jax.jit
def _solve_step(model, integrator, state, dt):
    return integrator.step(model, state, dt, integrator.init(model, state, dt))


def random_bordered(n, b, q, seed=0):
    """A diagonally dominant random bordered block-cyclic matrix ``A`` and a right-hand side
    ``(r_b (n, b), r_r (q,))``: ``(A, r_b, r_r)``."""
    rng = np.random.default_rng(seed)
    return BorderedBlockCyclic(
        diag=jnp.asarray(rng.normal(size=(n, b, b)) + 8 * np.eye(b)),
        lower=jnp.asarray(rng.normal(size=(n, b, b))),
        upper=jnp.asarray(rng.normal(size=(n, b, b))),
        C=jnp.asarray(rng.normal(size=(n, b, q))),
        D=jnp.asarray(rng.normal(size=(n, q, b))),
        E=jnp.asarray(rng.normal(size=(q, q)) + 8 * np.eye(q)),
    ), jnp.asarray(rng.normal(size=(n, b))), jnp.asarray(rng.normal(size=q))


def pretensioned_idle_translated_machine():
    """A coarse ``two-roller-1d`` belt (5 elements per arc, 6 per span), 863 mm long (shorter than
    the path: pre-tension rows), the idle roller 0.5 mm out along x: a small DAE for one-step checks."""
    def machine(d):
        d["mesh"].update(roller_elements=[5, 5], free_elements=[6, 6])
        d["belt"]["length_mm"] = 863.0
        d["roller"][1]["translation_mm"] = [0.5, 0.0, 0.0]

    return load(scene_with(machine))[0]


def perturbed_state(model, seed: int = 0, moved_masses: bool = True):
    """The initial state with belt displacements and velocities and the roller states perturbed at
    random; with ``moved_masses`` the element masses no longer uniform (as the source transport rule
    moves them), else the model's (as the shift rule keeps them)."""
    s = jb.initial_state(model)
    rng = np.random.default_rng(seed)
    n, b, q = model.n_xi, model.block, model.n_roller_dofs
    u, u_dot = s.u + 1e-5 * rng.standard_normal((n, b)), s.u_dot + 1e-3 * rng.standard_normal((n, b))
    chi, chi_dot = s.chi + 1e-4 * rng.standard_normal(q), s.chi_dot + 1e-2 * rng.standard_normal(q)
    m_e = s.m_e * (1.0 + 0.2 * rng.random(n)) if moved_masses else s.m_e
    return eqx.tree_at(lambda s: (s.u, s.u_dot, s.chi, s.chi_dot, s.m_e), s, (u, u_dot, chi, chi_dot, m_e))


def dense_backward_euler(model, state, dt):
    """``(x₁, ẋ₁)`` of one Backward-Euler step ``(M + Δt² K) ẍ = F − K (x + Δt ẋ)`` by a dense numpy
    solve."""
    K, M = jax.jit(dae_matrices)(model, state.m_e)
    K, M = np.asarray(K.to_dense()), np.asarray(M.to_dense())
    F = np.asarray(join(*dae_rhs(model, state.u, state.chi, dt)))
    x0, v0 = np.asarray(join(state.u, state.chi)), np.asarray(join(state.u_dot, state.chi_dot))
    a = np.linalg.solve(M + dt ** 2 * K, F - K @ (x0 + dt * v0))
    v1 = v0 + dt * a
    return x0 + dt * v1, v1


def dense_block_tridiagonal(diag, lower, upper):
    """The assembled matrix of blocks: row block ``i`` holds ``lower[i]`` at column block ``i-1``,
    ``diag[i]`` at ``i``, ``upper[i]`` at ``i+1`` (``lower[0]`` and ``upper[-1]`` fall outside)."""
    m, b = diag.shape[:2]
    A = np.zeros((m * b, m * b))
    for i in range(m):
        A[i * b:(i + 1) * b, i * b:(i + 1) * b] = diag[i]
        if i:
            A[i * b:(i + 1) * b, (i - 1) * b:i * b] = lower[i]
        if i < m - 1:
            A[i * b:(i + 1) * b, (i + 1) * b:(i + 2) * b] = upper[i]
    return A
