"""Shared test helpers: scene dictionaries and finite differences."""

import copy
import tomllib
from importlib import resources

import numpy as np

import jaxbelt as jb


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
    """The smallest run length ``≥ n_steps`` that is a whole number of the time loop's checkpoint
    chunks (``jaxbelt.timeloop.default_checkpoint_chunk``): its compiled scan then holds one copy
    of the step, not a second one for the remainder (about a third less to compile)."""
    from jaxbelt.timeloop import default_checkpoint_chunk

    n = n_steps
    while n > default_checkpoint_chunk(n) and n % default_checkpoint_chunk(n):
        n += 1
    return n
