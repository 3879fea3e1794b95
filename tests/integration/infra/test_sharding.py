"""jaxbelt.infra.sharding: batched_map over 4 forced CPU devices, distributed_map over 2 processes.

Device counts and jax.distributed must be set before jax starts, so those checks run in
subprocesses (CPU only, bounded by timeouts).
"""

import os
import socket
import subprocess
import sys
import textwrap

import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt.infra import sharding

TIMEOUT_S = 240

# The belt metric of the checks: final longitudinal tracer displacements after 20 steps, as a
# function of the x translations (m) of the two rollers.
METRIC = textwrap.dedent("""
    import jax, jax.numpy as jnp, numpy as np
    import jaxbelt as jb
    from jaxbelt.infra import sharding
    jb.enable_x64()
    scene = jb.load_scene("two-roller-1d-idle-translated")
    model, opts = jb.build_model(scene), jb.RunOptions.from_scene(scene)
    def fn(th):
        return jb.simulate(jb.with_misalignment(model, translation=th), opts.solver, n_steps=20,
                           dt=opts.dt)[1].tracer_u[-1]
    def configs(n):
        k = np.arange(n, dtype=float)
        return np.stack([1e-3 * np.sin(k), 5e-4 * np.cos(k)], axis=1)
""")

FOUR_DEVICES = METRIC + textwrap.dedent("""
    assert len(jax.devices()) == 4, jax.devices()
    mesh = sharding.config_mesh()
    assert mesh.axis_names == ("configs",) and mesh.size == 4

    th = configs(6)
    ref = np.asarray(jax.jit(jax.vmap(fn))(jnp.asarray(th)))

    traces = []
    def counted(t):
        traces.append(1)
        return fn(t)
    whole = sharding.batched_map(counted, th)                  # 6 -> padded to 8
    np.testing.assert_allclose(whole, ref, rtol=1e-12, atol=1e-15)

    # the padded batch really lies on 4 devices, 2 rows each (same executable, cached)
    out = sharding._run_sharded(counted, sharding._pad_rows(th, 8), mesh)
    assert len(out.sharding.device_set) == 4, out.sharding
    assert out.sharding.spec == jax.sharding.PartitionSpec("configs"), out.sharding
    assert {s.data.shape[0] for s in out.addressable_shards} == {2}
    assert len(traces) == 1, len(traces)

    seen = []
    chunked = sharding.batched_map(counted, th, chunk=3,       # chunks of 4: 4 + (2 -> 4)
                                   progress=lambda done, part: seen.append((done, part.shape)))
    np.testing.assert_allclose(chunked, ref, rtol=1e-12, atol=1e-15)
    assert seen == [(4, (4, ref.shape[1])), (6, (2, ref.shape[1]))], seen
    n_traces = len(traces)
    assert n_traces == 2, n_traces                             # one per block size (8, 4)
    again = sharding.batched_map(counted, configs(5), chunk=4)  # same fn and size: cached
    np.testing.assert_allclose(again, ref[:5], rtol=1e-12, atol=1e-15)
    assert len(traces) == n_traces, len(traces)

    # an operand (the model) is an argument of the program, replicated on the devices: another
    # model of the same shapes reuses the compilation and gives its own results
    op_traces = []
    def with_model(m, t):
        op_traces.append(1)
        return jb.simulate(jb.with_misalignment(m, translation=t), opts.solver, n_steps=20, dt=opts.dt)[1].tracer_u[-1]
    by_operand = sharding.batched_map(with_model, th, operand=model)
    np.testing.assert_allclose(by_operand, ref, rtol=1e-12, atol=1e-15)
    stiffer = jb.build_model(scene.replace(belt=scene.belt.__class__(**{**scene.belt.__dict__,
                                                                          "youngs_modulus": 2 * scene.belt.youngs_modulus})))
    other = sharding.batched_map(with_model, th, operand=stiffer)
    assert len(op_traces) == 1, len(op_traces)
    assert not np.allclose(other, by_operand)
    direct = np.asarray(jax.vmap(lambda t: with_model(stiffer, t))(jnp.asarray(th)))
    np.testing.assert_allclose(other, direct, rtol=1e-12, atol=1e-15)
    print("OK")
""")

WORKER = METRIC + textwrap.dedent("""
    import sys
    pid, out = int(sys.argv[1]), sys.argv[2]
    assert jax.process_count() == 2 and jax.process_index() == pid
    assert len(jax.local_devices()) == 2 and len(jax.devices()) == 4
    np.save(out, sharding.distributed_map(fn, configs(7), chunk=2))
    print("OK", pid)
""")


def _devices(n):
    """XLA_FLAGS for ``n`` forced CPU devices, keeping the suite's compile flags (tests/conftest.py)."""
    return f"{os.environ.get('XLA_FLAGS', '')} --xla_force_host_platform_device_count={n}".strip()


def _env(**extra):
    env = dict(os.environ, JAX_PLATFORMS="cpu", OPENBLAS_NUM_THREADS="1", **extra)
    for k in ("JAXBELT_COORDINATOR", "JAXBELT_NUM_PROCESSES", "JAXBELT_PROCESS_ID", "SLURM_NTASKS",
              "JAX_COORDINATOR_ADDRESS", "JAX_COORDINATOR_BIND_ADDRESS"):
        if k not in extra:
            env.pop(k, None)
    return env


def test_batched_map_over_four_cpu_devices_equals_vmap():
    env = _env(XLA_FLAGS=_devices(4))
    r = subprocess.run([sys.executable, "-c", FOUR_DEVICES], env=env, capture_output=True,
                       text=True, timeout=TIMEOUT_S)
    assert r.returncode == 0 and "OK" in r.stdout, r.stdout + r.stderr[-4000:]


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_distributed_map_two_processes_equals_single_process(tmp_path):
    port = _free_port()
    procs = []
    for pid in range(2):
        env = _env(XLA_FLAGS=_devices(2),
                   JAXBELT_COORDINATOR=f"127.0.0.1:{port}", JAXBELT_NUM_PROCESSES="2",
                   JAXBELT_PROCESS_ID=str(pid), JAX_COORDINATOR_BIND_ADDRESS=f"127.0.0.1:{port}")
        script = "from jaxbelt.infra import sharding; assert sharding.initialize_from_env()\n" + WORKER
        procs.append(subprocess.Popen(
            [sys.executable, "-c", script, str(pid), str(tmp_path / f"out{pid}.npy")],
            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
    logs = []
    try:
        for p in procs:
            out, err = p.communicate(timeout=TIMEOUT_S)
            logs.append(out + err[-4000:])
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()
    assert all(p.returncode == 0 for p in procs), "\n----\n".join(logs)

    ns = {}
    exec(METRIC, ns)
    ref = sharding.batched_map(ns["fn"], ns["configs"](7))
    assert ref.shape[0] == 7
    for pid in range(2):
        np.testing.assert_allclose(np.load(tmp_path / f"out{pid}.npy"), ref, rtol=1e-12, atol=1e-15)


def test_batched_map_pytree_progress_and_empty():
    def fn(th):
        return {"s": jnp.sum(th), "twice": 2 * th}

    th = np.arange(10.0).reshape(5, 2)
    calls = []
    out = sharding.batched_map(fn, th, chunk=2, progress=lambda done, part: calls.append(done))
    np.testing.assert_array_equal(out["s"], th.sum(axis=1))
    np.testing.assert_array_equal(out["twice"], 2 * th)
    assert isinstance(out["s"], np.ndarray) and calls == [2, 4, 5]
    np.testing.assert_array_equal(sharding.distributed_map(fn, th)["twice"], 2 * th)
    empty = sharding.batched_map(fn, np.zeros((0, 2)))
    assert empty["s"].shape == (0,) and empty["twice"].shape == (0, 2)
    with pytest.raises(ValueError):
        sharding.batched_map(fn, th, chunk=0)


def test_initialize_from_env_is_a_no_op_without_a_launcher(monkeypatch):
    for k in ("JAXBELT_COORDINATOR", "SLURM_NTASKS"):
        monkeypatch.delenv(k, raising=False)
    assert sharding.initialize_from_env() is False
    monkeypatch.setenv("SLURM_NTASKS", "1")
    assert sharding.initialize_from_env() is False
