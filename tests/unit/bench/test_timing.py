"""The benchmarks' timing helpers (:mod:`jaxbelt.bench.timing`) with a scripted clock: best-of timings
in interleaved rounds (the call order A, B, A, B, the inner repeats, the progress callback), the
first call of a warm timing kept apart and the repeats stopped by the budget; the memory figure of a
compiled program against its argument and output sizes (an aliased output counted once); the result
files with the machine they ran on."""

import itertools
import json
import os
import platform

import equinox as eqx
import jax
import jax.numpy as jnp
import pytest

from jaxbelt.bench import timing


class ScriptedClock:
    """A stand-in for :func:`timing.clock`: calls the function and reports the next scripted time."""

    def __init__(self, times):
        self.times = iter(times)
        self.calls = []

    def __call__(self, fn, *args):
        out = fn(*args)
        self.calls.append(out)
        return next(self.times), out


def test_clock_returns_the_wall_time_and_the_result():
    seconds, out = timing.clock(lambda a, b: jnp.arange(3.0) * a + b, 2.0, 1.0)
    assert seconds > 0 and out.tolist() == [1.0, 3.0, 5.0]


def test_interleaved_rounds_keep_the_best_time_of_each_candidate(monkeypatch):
    clock = ScriptedClock([5.0, 2.0, 3.0,  # round 1: A, B, B (B twice a round)
                           4.0, 2.5, 1.0])  # round 2
    monkeypatch.setattr(timing, "clock", clock)
    progress = []
    best = timing.interleaved_best({"A": lambda: "a", "B": lambda: "b"}, rounds=2, inner={"B": 2},
                                   progress=lambda r, n: progress.append((r, n)))
    assert best == {"A": 4.0, "B": 1.0}
    assert clock.calls == ["a", "b", "b", "a", "b", "b"]
    assert progress == [(1, 2), (2, 2)]


def test_interleaved_rounds_with_one_inner_count_for_all(monkeypatch):
    clock = ScriptedClock([3.0, 1.0, 2.0, 4.0, 0.5, 6.0])
    monkeypatch.setattr(timing, "clock", clock)
    assert timing.interleaved_best({"A": lambda: "a", "B": lambda: "b"}, rounds=1, inner=3) == {"A": 1.0, "B": 0.5}
    assert clock.calls == ["a"] * 3 + ["b"] * 3


def test_warm_best_times_the_first_call_apart_and_repeats_until_the_budget(monkeypatch):
    counter = itertools.count(1)
    clock = ScriptedClock([9.0, 0.2, 0.1, 0.3, 0.4, 0.05])
    monkeypatch.setattr(timing, "clock", clock)
    out, best, first = timing.warm_best(lambda: next(counter), repeat=10, budget_s=0.5)
    # repeats until their sum reaches the budget: 0.2 + 0.1 + 0.3 = 0.6 >= 0.5 after three
    assert (out, best, first) == (4, 0.1, 9.0)
    assert len(clock.calls) == 4


def test_warm_best_stops_at_the_repeat_count_and_once_without_repeats(monkeypatch):
    monkeypatch.setattr(timing, "clock", ScriptedClock([2.0, 0.3, 0.2, 0.25, 7.0]))
    assert timing.warm_best(lambda: "x", repeat=3, budget_s=100.0) == ("x", 0.2, 2.0)
    monkeypatch.setattr(timing, "clock", clock := ScriptedClock([1.5, 7.0]))
    assert timing.warm_best(lambda: "y", repeat=0) == ("y", 1.5, 1.5)
    assert len(clock.calls) == 1


def test_compiled_bytes_are_arguments_and_outputs_with_aliases_counted_once():
    x = jnp.zeros(1000)  # 8000 bytes in float64
    assert timing.compiled_bytes(jax.jit(lambda a: a * 2.0).lower(x).compile()) == 16000
    assert timing.compiled_bytes(jax.jit(lambda a: a * 2.0, donate_argnums=0).lower(x).compile()) == 8000
    # equinox's compiled wrapper: the XLA program inside it (its outputs as a tuple: a few bytes more)
    assert 16000 <= timing.compiled_bytes(eqx.filter_jit(lambda a: a * 2.0).lower(x).compile()) <= 16000 + 64
    assert timing.compiled_bytes(object()) is None  # no memory analysis


def test_machine_describes_this_process(monkeypatch):
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "3")
    m = timing.machine()
    assert m["python"] == platform.python_version() and m["jax"] == jax.__version__
    assert m["cpu_count"] == os.cpu_count() and m["openblas_num_threads"] == "3"
    assert m["x64"] is True and m["device"] == str(jax.devices()[0])
    monkeypatch.delenv("OPENBLAS_NUM_THREADS")
    assert timing.machine()["openblas_num_threads"] is None


def test_write_json_puts_the_machine_beside_the_payload(tmp_path):
    path = timing.write_json(tmp_path / "new" / "dir", "speed", {"rows": {"a": 1.5}, "scene": "s"})
    assert path == tmp_path / "new" / "dir" / "speed.json"
    data = json.loads(path.read_text())
    assert list(data) == ["machine", "rows", "scene"]
    assert data["rows"] == {"a": 1.5} and data["machine"] == timing.machine()


def test_a_payload_key_named_machine_wins(tmp_path):
    path = timing.write_json(tmp_path, "x", {"machine": "mine"})
    assert json.loads(path.read_text()) == {"machine": "mine"}


@pytest.mark.parametrize("repeat", [1, 2])
def test_warm_best_with_the_real_clock_returns_the_last_result(repeat):
    calls = []
    out, best, first = timing.warm_best(lambda: calls.append(1) or len(calls), repeat=repeat, budget_s=10.0)
    assert out == repeat + 1 and 0 < best and 0 < first
