"""Compiled programs kept on disk between processes: :func:`stored_jit`.

JAX's persistent compilation cache skips XLA's compilation in a second process, but not the Python
tracing and MLIR lowering that come before its lookup, and for the large programs of a design
command (a steady solve with its Newton–GMRES loops, its tangents, a batch of them) those are most
of a warm command's time. :func:`stored_jit` is :func:`equinox.filter_jit` that, where a store is
switched on (:func:`use_program_store`; the command line does), also keeps each traced program as
serialised StableHLO (:func:`jax.export.export`) under a key of everything that defines it, and in
a later process loads it instead of tracing: a call then costs the module's loading, JAX's
compilation-cache lookup of it (the compilation cache holds the executable) and its run. The
executable itself is not what is kept: XLA:CPU executables deserialised side by side in one
process were measured to fail at run time (a kernel "not found"), while the compilation cache's
own path is JAX's tested one.

**The key** is a SHA-256 of: the function's module and name; a digest of the package's own source
files (any change to jaxbelt's code is a new program); the versions of jax and jaxlib, the backend
and its devices, the precision setting; the structure of the arguments with every static
(non-array) field's value; and each array argument's shape, dtype and weak type. Static values
are written out in full (arrays by a digest of their bytes, functions by their qualified name); a
value whose text would not identify it across processes (an object shown by its address, a lambda
or a local function) makes the call an ordinary ``filter_jit`` call, never a guess.

Calls under a transformation (``jit``, ``grad``, ``vmap``: an argument is a tracer) are ordinary
``filter_jit`` calls, so differentiating through a stored function is unchanged. A program that
cannot be exported (a host callback) is an ordinary call and not kept.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
import pickle
import sys
import tempfile
from pathlib import Path

import equinox as eqx
import jax
import jaxlib
import numpy as np

_STORE: list[Path | None] = [None]
_LOADED: dict[str, tuple] = {}  # key -> (jitted call of the loaded program, output skeleton), this process
_SOURCE_DIGEST: list[str] = []
_UNSTABLE = (" at 0x", "<lambda>", "<locals>")


def use_program_store(path) -> Path | None:
    """Switch the store on at ``path`` (a folder, created; ``None`` switches it off). **Returns:**
    the folder."""
    _STORE[0] = None if path is None else Path(path)
    if _STORE[0] is not None:
        _STORE[0].mkdir(parents=True, exist_ok=True)
    _LOADED.clear()
    return _STORE[0]


def program_store() -> Path | None:
    """The store's folder, ``None`` where it is off."""
    return _STORE[0]


PACKAGE_ROOT = Path(__file__).resolve().parents[1]  # the jaxbelt package (this module lives in jaxbelt/infra)


def source_files() -> list[Path]:
    """Every ``.py`` file of the package, in a fixed order: what :func:`source_digest` reads."""
    return sorted(PACKAGE_ROOT.rglob("*.py"))


def source_digest() -> str:
    """SHA-256 of the package's ``.py`` files (names and contents), computed once per process."""
    if not _SOURCE_DIGEST:
        h = hashlib.sha256()
        root = PACKAGE_ROOT
        for p in source_files():
            h.update(str(p.relative_to(root)).encode())
            h.update(p.read_bytes())
        _SOURCE_DIGEST.append(h.hexdigest())
    return _SOURCE_DIGEST[0]


@dataclasses.dataclass(frozen=True)
class _Slot:
    """Where the ``index``-th array output goes in a stored program's output skeleton."""
    index: int


def _static_text(x) -> str:
    if isinstance(x, (np.ndarray, np.generic)):
        a = np.ascontiguousarray(x)
        return f"ndarray{a.shape}{a.dtype}:{hashlib.sha256(a.tobytes()).hexdigest()}"
    if callable(x) and hasattr(x, "__qualname__") and not isinstance(x, type):
        return f"fn:{getattr(x, '__module__', '')}.{x.__qualname__}"
    with np.printoptions(threshold=sys.maxsize):
        return repr(x)


def program_key(fn, args, kwargs):
    """``(key, leaves, program)`` of a call: its key (``None`` where the call cannot be identified
    across processes), its array arguments, and ``program(arrays, box)``, the call as a function of
    those arrays alone (its array outputs as a list; the output's skeleton, the non-array parts and
    where each array goes, appended to ``box``)."""
    dyn, static = eqx.partition((args, kwargs), eqx.is_array)
    leaves, in_tree = jax.tree.flatten(dyn)
    if any(isinstance(x, jax.core.Tracer) for x in leaves):
        return None, leaves, None
    static_leaves, static_tree = jax.tree.flatten(static)
    devices = ",".join(d.device_kind for d in jax.devices())
    parts = [f"{fn.__module__}.{fn.__qualname__}", source_digest(), jax.__version__, jaxlib.__version__,
             jax.default_backend(), devices, str(jax.config.jax_enable_x64), str(in_tree), str(static_tree)]
    parts += [_static_text(x) for x in static_leaves]
    parts += [f"{np.shape(x)}{x.dtype}{getattr(x, 'weak_type', False)}" for x in leaves]
    text = "\n".join(parts)
    key = None if any(u in text for u in _UNSTABLE) else hashlib.sha256(text.encode()).hexdigest()

    def program(arrays, box):
        a, k = eqx.combine(jax.tree.unflatten(in_tree, arrays), static)
        out_leaves, out_tree = jax.tree.flatten(fn(*a, **k))
        slots, outputs = [], []
        for x in out_leaves:
            if eqx.is_array(x):
                slots.append(_Slot(len(outputs)))
                outputs.append(x)
            else:
                slots.append(x)
        box.append(jax.tree.unflatten(out_tree, slots))
        return outputs

    return key, leaves, program


def _fill(skeleton, outputs):
    return jax.tree.map(lambda s: outputs[s.index] if isinstance(s, _Slot) else s, skeleton,
                        is_leaf=lambda s: isinstance(s, _Slot))


def _load(path: Path):
    try:
        with open(path, "rb") as fh:
            payload, skeleton = pickle.load(fh)
        return jax.jit(jax.export.deserialize(bytearray(payload)).call), skeleton
    except Exception:  # a damaged or foreign file: traced again and rewritten
        return None


def _save(path: Path, exported, skeleton):
    try:
        blob = pickle.dumps((bytes(exported.serialize()), skeleton))
    except Exception:  # an output that does not pickle: not kept
        return
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    with os.fdopen(fd, "wb") as fh:
        fh.write(blob)
    os.replace(tmp, path)  # atomic: a concurrent process reads the old file or the new one


def _committed(leaves):
    """The arguments all placed on one device, where they are not spread over several: jit keys a
    call on its arguments' placement, so a call whose arguments are NumPy arrays or fresh
    (uncommitted) arrays and one with the results of earlier computations (committed to their
    device) would otherwise be two signatures of the same program, compiled twice."""
    devices = {d for x in leaves if isinstance(x, jax.Array) and getattr(x, "committed", False)
               for d in x.devices()}
    if len(devices) > 1:
        return leaves
    return jax.device_put(leaves, devices.pop() if devices else jax.devices()[0])


def stored_jit(fn):
    """:func:`equinox.filter_jit` of ``fn`` whose traced programs are kept in the program store
    when it is on (module docstring)."""
    jitted = eqx.filter_jit(fn)

    @functools.wraps(fn)
    def call(*args, **kwargs):
        store = _STORE[0]
        if store is None:
            return jitted(*args, **kwargs)
        key, leaves, program = program_key(fn, args, kwargs)
        if key is None:
            return jitted(*args, **kwargs)
        hit = _LOADED.get(key)
        path = store / f"{key}.program"
        if hit is None and path.exists():
            hit = _load(path)
        if hit is None:
            box = []
            specs = [jax.ShapeDtypeStruct(np.shape(x), x.dtype, weak_type=getattr(x, "weak_type", False))
                     for x in leaves]
            try:
                exported = jax.export.export(jax.jit(lambda arrays: program(arrays, box)))(specs)
            except Exception:  # what StableHLO cannot carry (a host callback): an ordinary call
                return jitted(*args, **kwargs)
            hit = (jax.jit(exported.call), box[0])
            _save(path, exported, box[0])
        _LOADED[key] = hit
        executable, skeleton = hit
        return _fill(skeleton, executable(_committed(leaves)))

    call.jitted = jitted
    call.lower = jitted.lower
    return call
