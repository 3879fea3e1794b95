"""Pieces shared by the command modules: the two error kinds that :func:`jaxbelt.cli.main` turns
into a one-line message and an exit code, scene loading with the command-line overrides, checks
of numeric options, timing and output helpers."""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from ..build import build_model
from ..mesh import build_mesh
from ..scene import load_scene
from ..timeloop import RunOptions

SCENE_HELP = "TOML path or built-in scene name"


class UsageError(Exception):
    """Bad input from the user: ``jaxbelt: error: …`` on stderr, exit code 2."""


class SimulationError(Exception):
    """A run that went wrong (diverged): ``jaxbelt: error: …`` on stderr, exit code 3."""


def scene_from_args(scene_arg, t_end=None, dt=None, integrator=None, transport=None, linear_solver=None):
    """The scene of ``scene_arg`` with the command-line overrides of its ``[time]`` and ``[solver]``
    (``None``: the scene's own)."""
    scene = load_scene(scene_arg)
    if t_end is not None or dt is not None:
        t = scene.time
        t_end = t.t_end if t_end is None else t_end
        dt = t.dt if dt is None else dt
        for key, v in (("--t-end", t_end), ("--dt", dt)):
            if not np.isfinite(v) or v <= 0:
                raise UsageError(f"{key} = {v}: must be a positive number")
        if t_end < dt:
            raise UsageError(f"--t-end = {t_end}: shorter than one step (dt = {dt})")
        scene = scene.replace(time=dataclasses.replace(t, t_end=float(t_end), dt=float(dt)))
    t = scene.time
    if abs(t.n_steps * t.dt - t.t_end) > 1e-9 * t.t_end:
        print(f"jaxbelt: note: t_end = {t.t_end:g} s is not a whole number of steps of dt = {t.dt:g} s; the run "
              f"takes {t.n_steps} steps and ends at {t.n_steps * t.dt:g} s", file=sys.stderr)
    if integrator is not None:
        scene = scene.replace(solver=dataclasses.replace(scene.solver, integrator=integrator))
    if transport is not None:
        scene = scene.replace(solver=dataclasses.replace(scene.solver, transport=transport))
    if linear_solver is not None:
        scene = scene.replace(solver=dataclasses.replace(scene.solver, linear_solver=linear_solver))
    return scene


def load_run(scene_arg, t_end=None, dt=None, integrator=None, transport=None, linear_solver=None):
    """``(scene, mesh, model, options)`` of a scene with the command-line overrides
    (:func:`scene_from_args`): its grid, its model (:func:`jaxbelt.build_model`) and its run
    settings (:class:`jaxbelt.RunOptions`)."""
    scene = scene_from_args(scene_arg, t_end, dt, integrator, transport, linear_solver)
    mesh = build_mesh(scene)
    return scene, mesh, build_model(scene, mesh), RunOptions.from_scene(scene)


def rebuild(scene):
    """``(scene, mesh, model, options)`` of a scene already loaded (another grid of it)."""
    mesh = build_mesh(scene)
    return scene, mesh, build_model(scene, mesh), RunOptions.from_scene(scene)


def output_file(option, path, kind="figure"):
    """The file an output option will write, checked before anything runs: its folder exists and
    it is not a folder itself; a figure's suffix is a format matplotlib writes (none: PNG); an
    archive (``kind="npz"``) gains the ``.npz`` that :func:`numpy.savez` appends, so that what is
    reported is the file written. **Returns:** the path (str), or ``None`` for ``None``. Raises
    :class:`UsageError` naming the option."""
    if path is None:
        return None
    p = Path(path)
    if str(path) == "" or p.is_dir():
        raise UsageError(f"{option} = {str(path)!r}: is a folder; give a file name")
    if not p.resolve().parent.is_dir():
        raise UsageError(f"{option} = {str(path)!r}: the folder {str(p.resolve().parent)!r} does not exist")
    if kind == "npz":
        return str(p) if p.suffix == ".npz" else str(p) + ".npz"
    if p.suffix:
        from matplotlib.backend_bases import FigureCanvasBase

        formats = FigureCanvasBase.get_supported_filetypes()
        if p.suffix[1:].lower() not in formats:
            raise UsageError(f"{option} = {str(path)!r}: {p.suffix!r} is not a figure format matplotlib writes "
                             f"({', '.join(sorted(formats))})")
    return str(p)


def check_at_least(name, v, low=1):
    if v is not None and v < low:
        raise UsageError(f"{name} = {v}: must be at least {low}")


def finite_or_none(v):
    v = float(v)
    return v if np.isfinite(v) else None


def fmt(v, unit=""):
    return "nan" if v is None else f"{v:.4g}{unit}"


def print_json(data):
    print(json.dumps(data, indent=2))


def emit(args, data, print_text):
    """``data`` as JSON with ``--json``, else ``print_text(data)``."""
    if args.json:
        print_json(data)
    else:
        print_text(data)
