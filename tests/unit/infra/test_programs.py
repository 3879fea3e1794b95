"""The program store (:mod:`jaxbelt.infra.programs`): a stored program gives what ``filter_jit`` gives,
a later process loads it without tracing, and a call it cannot identify is never stored."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt.infra import programs

TRACES = []


class Spring(eqx.Module):
    k: jax.Array
    name: str = eqx.field(static=True)
    power: int = eqx.field(static=True)


@programs.stored_jit
def energy(s: Spring, x, scale=1.0):
    TRACES.append(s.name)  # runs only while tracing
    return {"e": scale * 0.5 * s.k * jnp.sum(x ** s.power), "label": s.name, "n": x.shape[0]}


@pytest.fixture
def store(tmp_path):
    programs.use_program_store(tmp_path)
    TRACES.clear()
    yield tmp_path
    programs.use_program_store(None)


def test_store_off_is_filter_jit():
    assert programs.program_store() is None
    out = energy(Spring(jnp.asarray(2.0), "a", 2), jnp.arange(3.0))
    assert float(out["e"]) == pytest.approx(5.0)


def test_stored_program_equals_filter_jit_and_is_loaded_without_tracing(store):
    s, x = Spring(jnp.asarray(3.0), "a", 2), jnp.linspace(0.0, 1.0, 5)
    ref = energy.jitted(s, x)
    TRACES.clear()
    out = energy(s, x)
    assert float(out["e"]) == float(ref["e"]) and out["label"] == "a" and out["n"] == 5
    assert TRACES == ["a"] and len(list(store.glob("*.program"))) == 1
    programs._LOADED.clear()  # a new process: only the file is left
    again = energy(s, x)
    assert TRACES == ["a"], "a stored program was traced again"
    assert float(again["e"]) == float(ref["e"]) and again["label"] == "a"
    # another array value: the same program
    assert float(energy(Spring(jnp.asarray(1.0), "a", 2), x)["e"]) == pytest.approx(float(ref["e"]) / 3)
    assert TRACES == ["a"]


def test_numpy_fresh_and_computed_arguments_run_one_compiled_program(store):
    """A call with NumPy arguments, one with fresh arrays and one with the results of earlier
    computations (committed to their device) are one program: one XLA compilation, not three."""
    k, x = np.asarray(3.0), np.linspace(0.0, 1.0, 5)
    energy(Spring(k, "b", 2), x)
    energy(Spring(jnp.asarray(k), "b", 2), jnp.asarray(x))
    energy(Spring(jnp.sin(jnp.asarray(k)), "b", 2), jnp.cos(jnp.asarray(x)))
    (executable, _), = programs._LOADED.values()
    assert executable._cache_size() == 1


def test_every_static_value_and_array_signature_is_in_the_key(store):
    x = jnp.arange(4.0)
    energy(Spring(jnp.asarray(1.0), "a", 2), x)
    energy(Spring(jnp.asarray(1.0), "a", 3), x)  # a static field
    energy(Spring(jnp.asarray(1.0), "b", 2), x)
    energy(Spring(jnp.asarray(1.0), "a", 2), x, scale=2.0)  # a static argument
    energy(Spring(jnp.asarray(1.0), "a", 2), jnp.arange(5.0))  # a shape
    energy(Spring(jnp.asarray(1.0), "a", 2), jnp.arange(4, dtype=jnp.float32))  # a dtype
    assert len(TRACES) == 6 and len(list(store.glob("*.program"))) == 6
    assert float(energy(Spring(jnp.asarray(1.0), "a", 3), x)["e"]) == pytest.approx(0.5 * 36)


def test_static_values_without_a_stable_text_are_not_stored(store):
    @programs.stored_jit
    def apply(f, x):
        return f(x)

    out = apply(lambda v: 2 * v, jnp.ones(2))
    assert np.allclose(out, 2.0) and not list(store.glob("*.program"))
    key, _, _ = programs.program_key(apply, (object(), jnp.ones(2)), {})
    assert key is None


def test_differentiating_through_a_stored_function(store):
    x = jnp.linspace(0.0, 1.0, 4)
    g = jax.grad(lambda k: energy(Spring(k, "a", 2), x)["e"])(jnp.asarray(2.0))
    assert float(g) == pytest.approx(0.5 * float(jnp.sum(x ** 2)))
    assert not list(store.glob("*.program"))  # traced inside grad: an ordinary filter_jit call


def test_a_damaged_file_is_compiled_again(store):
    s, x = Spring(jnp.asarray(2.0), "a", 2), jnp.arange(3.0)
    energy(s, x)
    (path,) = store.glob("*.program")
    path.write_bytes(b"not a program")
    programs._LOADED.clear()
    assert float(energy(s, x)["e"]) == pytest.approx(5.0)
    assert len(TRACES) == 2 and path.stat().st_size > 100


def test_source_digest_reads_the_whole_package():
    """A stored program is keyed on every module it may have traced, not only the store's own
    package: a change to the steady solver or the time step must give new keys."""
    names = {p.relative_to(programs.PACKAGE_ROOT).as_posix() for p in programs.source_files()}
    assert {"__init__.py", "steady/fixed_point.py", "timeloop.py", "linalg/gmres.py", "infra/programs.py"} <= names
