"""Many misalignment configurations at once: batched, sharded over local devices, multi-process.

Three levels (``docs/scale.md``):

1. ``jax.vmap(fn)`` evaluates a batch of configurations on one device;
2. :func:`batched_map` shards that batch over every local device (a 1-axis
   :class:`jax.sharding.Mesh` named ``"configs"``, see :func:`config_mesh`), in chunks of
   bounded memory;
3. :func:`distributed_map` splits the configurations over the processes of a
   :func:`jax.distributed.initialize` run (:func:`initialize_from_env`), each process runs
   :func:`batched_map` on its own devices and every process receives the full result.

The configurations are independent, so there is no communication during the evaluation:
sharding the batch axis only places each device's rows on that device. The one collective is
the final gather of :func:`distributed_map` (``multihost_utils.process_allgather``); on CPU it
needs cross-process collectives, which jax 0.10 provides through gloo by default
(``jax_cpu_collectives_implementation = "gloo"``); older jax versions left it unset, and
:func:`initialize_from_env` then sets it before initialising.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import numpy as np
from jax.experimental import multihost_utils
from jax.sharding import Mesh, NamedSharding, PartitionSpec

AXIS = "configs"


def config_mesh(devices: Sequence[jax.Device] | None = None) -> Mesh:
    """A 1-axis mesh named ``"configs"`` over which the batch of configurations is split.

    **Arguments:** ``devices``: the devices to use; default every device of this process
    (``jax.local_devices()``, which is ``jax.devices()`` in a single-process run).

    **Returns:** a :class:`jax.sharding.Mesh` of shape ``(len(devices),)``, axis ``"configs"``.
    """
    devices = jax.local_devices() if devices is None else list(devices)
    if not devices:
        raise ValueError("config_mesh needs at least one device")
    return Mesh(np.asarray(devices, dtype=object), (AXIS,))


def _batched(fn: Callable, batch: Callable | None) -> Callable:
    """``fn`` over a leading batch axis: ``vmap``, or ``batch(fn, x)``."""
    return jax.vmap(fn) if batch is None else functools.partial(batch, fn)


@functools.lru_cache(maxsize=32)
def _jitted(fn: Callable, mesh: Mesh, batch: Callable | None):
    sharding = NamedSharding(mesh, PartitionSpec(AXIS))
    return jax.jit(_batched(fn, batch), in_shardings=sharding, out_shardings=sharding)


@functools.lru_cache(maxsize=32)
def _jitted_with_operand(fn: Callable, mesh: Mesh, batch: Callable | None):
    @eqx.filter_jit
    def run(operand, x):
        return _batched(lambda theta: fn(operand, theta), batch)(x)

    return run


def _compiled(fn, mesh, batch):
    """``jit(vmap(fn))`` (or ``batch``) with the batch axis sharded over ``mesh``, cached per
    ``(fn, mesh, batch)`` (jit then caches one executable per input shape)."""
    try:
        return _jitted(fn, mesh, batch)
    except TypeError:  # unhashable callable: no cache
        return _jitted.__wrapped__(fn, mesh, batch)


def _pad_rows(x: np.ndarray, rows: int) -> np.ndarray:
    """``x`` with its last row repeated up to ``rows`` rows."""
    if len(x) == rows:
        return x
    return np.concatenate([x, np.repeat(x[-1:], rows - len(x), axis=0)])


def _round_up(n: int, k: int) -> int:
    return -(-n // k) * k


def _run_sharded(fn, block: np.ndarray, mesh: Mesh, operand=None, batch=None):
    """Evaluate one padded block (rows a multiple of the mesh size); device arrays, sharded.
    With an ``operand``, its arrays are arguments of the compiled program, replicated on every
    device of the mesh (not constants folded into it)."""
    x = jax.device_put(block, NamedSharding(mesh, PartitionSpec(AXIS)))
    if operand is None:
        return _compiled(fn, mesh, batch)(x)
    arrays, rest = eqx.partition(operand, eqx.is_array)
    arrays = jax.device_put(arrays, NamedSharding(mesh, PartitionSpec()))
    return _jitted_with_operand(fn, mesh, batch)(eqx.combine(arrays, rest), x)


def batched_map(fn: Callable, configs, *, chunk: int | None = None, mesh: Mesh | None = None,
                progress: Callable | None = None, operand=None, batch: Callable | None = None):
    """Evaluate ``fn`` on every configuration, the batch sharded over the local devices.

    ``jax.vmap(fn)`` runs under ``jax.jit`` with the batch axis split over the mesh axis
    ``"configs"`` (``NamedSharding(mesh, PartitionSpec("configs"))`` on input and output).
    Each evaluated block is padded to a multiple of the device count by repeating its last
    configuration; the pad rows are dropped. The jitted function is cached per ``(fn, mesh)``,
    so repeated calls with the *same* ``fn`` object and block size compile once (a new
    ``lambda`` per call compiles again).

    **Arguments:**
    - ``fn``: ``fn(theta) -> pytree of arrays`` for one configuration ``theta`` (P,); with an
      ``operand``, ``fn(operand, theta)``.
    - ``operand``: a pytree (a model, a study) passed to every call as an argument of the
      compiled program: its arrays are traced, not folded in as constants, so one compilation
      serves every operand of the same shapes (a module-level ``fn`` compiles once per shape).
    - ``configs``: (n, P) configurations.
    - ``chunk``: evaluate at most this many configurations at a time (rounded up to a multiple
      of the device count; every chunk is padded to that size, so one compilation serves all),
      keeping device memory bounded (results collect on the host); default all n in one block.
    - ``mesh``: from :func:`config_mesh`; default all devices of this process.
    - ``progress``: optional callback ``progress(done, chunk_result)`` after each chunk, with
      ``done`` the number of configurations finished so far and ``chunk_result`` that chunk's
      pytree of numpy arrays (leading axis its configurations, pad rows removed).
    - ``batch``: ``batch(one, x)`` evaluates ``one`` over the rows of a block in place of
      ``jax.vmap(one)(x)`` (e.g. :func:`jaxbelt.steady.map_configurations` for steady solves).

    **Returns:** the pytree of ``fn``'s outputs stacked along a leading axis n, as numpy arrays.
    """
    configs = np.asarray(configs)
    if configs.ndim < 1:
        raise ValueError(f"configs must have a leading batch axis, got shape {configs.shape}")
    mesh = config_mesh() if mesh is None else mesh
    n = configs.shape[0]
    if n == 0:
        one = fn if operand is None else (lambda theta: fn(operand, theta))
        shapes = jax.eval_shape(jax.vmap(one), jax.ShapeDtypeStruct(configs.shape, configs.dtype))
        return jax.tree.map(lambda s: np.empty(s.shape, s.dtype), shapes)
    if chunk is not None and chunk < 1:
        raise ValueError(f"chunk must be a positive integer, got {chunk}")
    size = _round_up(min(n, chunk or n), mesh.size)

    parts = []

    def collect(out, start, m):
        part = jax.tree.map(lambda a: np.asarray(a)[:m], out)
        parts.append(part)
        if progress is not None:
            progress(start + m, part)

    pending = None
    for start in range(0, n, size):
        block = configs[start:start + size]
        out = _run_sharded(fn, _pad_rows(block, size), mesh, operand, batch)  # dispatched asynchronously
        if pending is not None:  # the previous chunk goes to the host while this one runs
            collect(*pending)
        pending = (out, start, len(block))
    collect(*pending)
    if len(parts) == 1:
        return parts[0]
    return jax.tree.map(lambda *xs: np.concatenate(xs, axis=0), *parts)


def distributed_map(fn: Callable, configs, *, chunk: int | None = None):
    """:func:`batched_map` over all processes of a :func:`jax.distributed.initialize` run.

    Every process must call it with the same ``configs``. Process ``jax.process_index()``
    takes the contiguous share ``[i s, (i + 1) s)``, ``s = ceil(n / jax.process_count())``
    (the list padded with its last configuration), evaluates it with :func:`batched_map` on its
    own devices and the shares are gathered with
    ``jax.experimental.multihost_utils.process_allgather``. With one process it is
    :func:`batched_map`.

    **Arguments:** ``fn``, ``configs`` (n, P) and ``chunk`` as in :func:`batched_map`
    (``chunk`` bounds each process's blocks).

    **Returns:** the full result, stacked along a leading axis n in the order of ``configs``,
    as numpy arrays, on every process.
    """
    configs = np.asarray(configs)
    n, n_proc = len(configs), jax.process_count()
    if n_proc == 1 or n == 0:
        return batched_map(fn, configs, chunk=chunk)
    share = -(-n // n_proc)
    i = jax.process_index()
    mine = _pad_rows(configs, share * n_proc)[i * share:(i + 1) * share]
    local = batched_map(fn, mine, chunk=chunk, mesh=config_mesh(jax.local_devices()))
    full = multihost_utils.process_allgather(local, tiled=True)
    return jax.tree.map(lambda a: np.asarray(a)[:n], full)


def initialize_from_env() -> bool:
    """Call :func:`jax.distributed.initialize` when the environment describes a multi-process run.

    Call it first, before any other jax work. ``JAXBELT_COORDINATOR`` (``host:port`` of process
    0), ``JAXBELT_NUM_PROCESSES`` and ``JAXBELT_PROCESS_ID`` give the run explicitly (any launcher
    can set them); otherwise a Slurm step with ``SLURM_NTASKS`` > 1 (started by ``srun``) is left
    to jax's own Slurm detection. Anything else is a single-process run and nothing happens.
    jax's variables ``JAX_COORDINATOR_BIND_ADDRESS``, ``JAX_COORDINATOR_PORT`` and
    ``JAX_LOCAL_DEVICE_IDS`` still apply.

    **Returns:** whether the run is multi-process (jax.distributed initialised).
    """
    env = os.environ
    if jax.distributed.is_initialized():
        return True
    if "JAXBELT_COORDINATOR" in env:
        try:
            kwargs = dict(coordinator_address=env["JAXBELT_COORDINATOR"],
                          num_processes=int(env["JAXBELT_NUM_PROCESSES"]),
                          process_id=int(env["JAXBELT_PROCESS_ID"]))
        except (KeyError, ValueError) as e:
            raise ValueError("JAXBELT_COORDINATOR needs integer JAXBELT_NUM_PROCESSES and "
                             f"JAXBELT_PROCESS_ID ({e!r})") from None
        if kwargs["num_processes"] <= 1:
            return False
    elif int(env.get("SLURM_NTASKS", "1")) > 1:
        kwargs = {}
    else:
        return False
    if jax.config.jax_cpu_collectives_implementation is None:  # older jax: no CPU gather otherwise
        jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(**kwargs)
    return True
