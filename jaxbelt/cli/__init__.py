"""Command line: ``jaxbelt demo | scenes | info | simulate | plot-scene | reduce | sensitivity | tolerance | sweep | tune | steering | bench``.

One module per command. A command module provides ``add_parser(subparsers)``, which registers its
sub-parser and sets its handler as ``func`` (``p.set_defaults(func=run)``, ``run(args) -> int``);
a new command is one import and one entry in :data:`COMMANDS`.

Every user error (bad scene, bad option) ends with a one-line message on stderr and exit code 2,
never a traceback; a diverged run ends with exit code 3. Commands signal these by raising
:class:`UsageError` (or :class:`jaxbelt.scene.SceneError`) and :class:`SimulationError`;
:func:`main` turns them into the message and the exit code.
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import warnings
from pathlib import Path

import jax

from .. import enable_x64
from ..infra.programs import use_program_store
from ..scene import MisalignmentWarning, SceneError
from . import bench, demo, info, plot_scene, reduce, scenes, sensitivity, simulate, steering, sweep, tolerance, tune
from ._common import SimulationError, UsageError
from .reduce import print_reduce

COMMANDS = (tolerance, sweep, sensitivity, tune, steering, demo, scenes, info, plot_scene, simulate, reduce, bench)  # in the order of ``jaxbelt --help``

__all__ = ["CLI_XLA_FLAGS", "COMMANDS", "SimulationError", "UsageError", "add_xla_flags", "build_parser",
           "configure_process", "main", "print_reduce", "xla_knows_flag"]


class _Parser(argparse.ArgumentParser):
    """argparse with its errors (missing or malformed options) as one line and exit code 2."""

    def error(self, message):
        print(f"jaxbelt: error: {message}", file=sys.stderr)
        sys.exit(2)


def build_parser():
    p = _Parser(prog="jaxbelt", description="Differentiable conveyor-belt simulator (JAX): tolerance design "
                                              "of roller misalignments, simulation, model order reduction")
    sub = p.add_subparsers(dest="cmd", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    return p


def enable_compilation_cache():
    """JAX's persistent compilation cache for the command line, on by default
    (``JAXBELT_COMPILATION_CACHE=0`` switches it off): a second call of the same command on the
    same scene shapes skips XLA compilation. Directory ``$JAXBELT_CACHE_DIR`` or
    ``$XDG_CACHE_HOME/jaxbelt/xla`` (``~/.cache/jaxbelt/xla``). **Returns:** the directory, or
    ``None`` where it is off. The large programs are also kept traced (serialised StableHLO) in its
    folder ``programs`` (:mod:`jaxbelt.infra.programs`): a later process loads them instead of tracing
    them again, which the compilation cache alone does not skip (``JAXBELT_PROGRAM_STORE=0`` switches
    that part off). Every program is kept, however quickly it compiled: a command runs
    about a hundred small programs (model build, static solve, bookkeeping) that take ~30 ms each
    to compile and ~5 ms to load, which a time threshold would recompile on every call."""
    if os.environ.get("JAXBELT_COMPILATION_CACHE", "1") == "0":
        return None
    path = os.environ.get("JAXBELT_CACHE_DIR") or str(
        Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "jaxbelt" / "xla")
    jax.config.update("jax_compilation_cache_dir", path)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    if os.environ.get("JAXBELT_PROGRAM_STORE", "1") != "0":
        use_program_store(Path(path) / "programs")
    return path


# XLA:CPU's classic elemental IR emitters instead of its newer MLIR fusion emitters: the
# command line's programs compile in about half the time and run as fast, the answers equal to
# round-off (``jaxbelt tolerance`` with an empty cache and with a warm one, both settings:
# benchmarks/tolerance_latency.py).
CLI_XLA_FLAGS = {"xla_cpu_use_fusion_emitters": "false"}


@functools.lru_cache(maxsize=None)
def xla_knows_flag(flag: str) -> bool:
    """Whether the installed jaxlib's XLA defines the flag ``flag`` (its name is in the library):
    an unknown flag in ``XLA_FLAGS`` aborts the process when the backend starts, and XLA retires
    flags from one release to the next. **Returns:** ``False`` where no jaxlib library is found."""
    import mmap
    from importlib.util import find_spec

    spec = find_spec("jaxlib")
    if spec is None or not spec.submodule_search_locations:
        return False
    libs = sorted(Path(spec.submodule_search_locations[0]).rglob("*.so"), key=lambda p: p.stat().st_size,
                  reverse=True)
    needle = flag.encode()
    for lib in libs[:2]:
        with open(lib, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as mm:
            if mm.find(needle) >= 0:
                return True
    return False


def add_xla_flags(flags: dict) -> dict:
    """Append ``--name=value`` to ``XLA_FLAGS`` for every flag the installed XLA defines and the
    caller's ``XLA_FLAGS`` does not set already (theirs win, flag by flag). Takes effect only before
    JAX starts its backend (the first computation). **Returns:** the flags added."""
    current = os.environ.get("XLA_FLAGS", "")
    added = {k: v for k, v in flags.items() if f"--{k}" not in current and xla_knows_flag(k)}
    if added:
        os.environ["XLA_FLAGS"] = " ".join([current] + [f"--{k}={v}" for k, v in added.items()]).strip()
    return added


def configure_process():
    """The process settings of the command line: float64 (:func:`jaxbelt.enable_x64`), one
    OpenBLAS thread unless the user chose otherwise, and :data:`CLI_XLA_FLAGS`. The LAPACK calls
    behind ``jnp.linalg`` (the reduced models' SVD, QR, eig) would otherwise spin extra OpenBLAS
    threads against XLA's own pool, which on a small, busy machine is several times slower; the
    variable is read when OpenBLAS loads, at the first LAPACK call."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    add_xla_flags(CLI_XLA_FLAGS)
    enable_x64()


def main(argv=None) -> int:
    default_show = warnings.showwarning

    cli_dir = str(Path(__file__).parent)

    def one_line(message, category, filename="", *a, **k):
        """The scene's range warnings and the commands' own as one line, others as usual."""
        if issubclass(category, MisalignmentWarning) or str(filename).startswith(cli_dir):
            print(f"jaxbelt: warning: {message}", file=sys.stderr)
        else:
            default_show(message, category, filename, *a, **k)

    args = build_parser().parse_args(argv)
    configure_process()
    # figures are written to files: a non-interactive backend unless the user chose one (the
    # library's plot functions never choose one, so that notebooks keep their inline backend)
    os.environ.setdefault("MPLBACKEND", "Agg")
    enable_compilation_cache()
    try:
        with warnings.catch_warnings():  # restores showwarning when the command returns
            warnings.showwarning = one_line
            return args.func(args)
    except (SceneError, UsageError) as e:
        print(f"jaxbelt: error: {e}", file=sys.stderr)
        return 2
    except SimulationError as e:
        print(f"jaxbelt: error: {e}", file=sys.stderr)
        return 3
