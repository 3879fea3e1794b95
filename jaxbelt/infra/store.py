"""Sweep results on disk: an xarray Dataset in a Zarr store, appended chunk by chunk.

Layout (dims ``config``, ``tracer``, ``param``):

| variable | dims | unit |
|---|---|---|
| ``theta`` | (config, param) | mm / mrad, deviation from the scene's misalignment |
| ``metric`` | (config,) | µm (µm/s for ``walk_rate``) |
| ``lateral_um``, ``longitudinal_um`` | (config, tracer) | µm, tracer deviation at ``t_eval`` |
| ``model`` | (config,) | int8: 0 = full model, 1 = reduced model (``flag_meanings``) |
| ``steering_mrad``, ``saturated`` | (config,) | steered machine only: largest actuator angle in the window, mrad; whether it reached the range (bool) |

The attributes hold the component labels of ``param`` (``param_labels``, JSON) and the study's
identity (``identity``, JSON: scene, metric, limit, seed, distribution, ``t_eval``); a rerun into
the same directory checks it and resumes after the configurations already stored, so a killed
sweep loses at most one chunk, and a rerun with more samples extends the sweep: the sample order
is fixed by the seed (:func:`jaxbelt.design.sampling.standard_normal_samples`), so the first
configurations are the same for any sample count.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

MODEL_CODES = {"full": 0, "reduced": 1}


def _xr():
    try:
        import xarray as xr
        import zarr  # noqa: F401
    except ImportError as e:  # pragma: no cover - both are dependencies
        raise RuntimeError("writing sweep results needs xarray and zarr (pip install xarray zarr)") from e
    return xr


def open_sweep(path: str | Path, identity: dict) -> int:
    """Number of configurations already stored under ``path`` for the same ``identity``
    (0 when there is no store). Raises ``ValueError`` if the store belongs to another study."""
    path = Path(path)
    if not (path / "zarr.json").exists() and not (path / ".zgroup").exists():
        if path.exists() and any(path.iterdir()):
            raise ValueError(f"--out = {str(path)!r}: exists and is not a sweep store")
        return 0
    xr = _xr()
    ds = xr.open_zarr(path, consolidated=False)
    stored = json.loads(ds.attrs.get("identity", "{}"))
    if stored != json.loads(json.dumps(identity)):
        diff = sorted(k for k in set(stored) | set(identity) if stored.get(k) != json.loads(json.dumps(identity)).get(k))
        raise ValueError(f"--out = {str(path)!r}: holds another sweep (differs in {', '.join(diff)}); use a new directory")
    return int(ds.sizes["config"])


def append_chunk(path: str | Path, identity: dict, labels, theta, outputs: dict, model: str | np.ndarray):
    """Append one chunk of configurations (creating the store on the first one)."""
    xr = _xr()
    theta = np.asarray(theta, float)
    n = theta.shape[0]
    if isinstance(model, str) and model not in MODEL_CODES:
        raise ValueError(f"model = {model!r}: one of {', '.join(MODEL_CODES)}")
    codes = np.full(n, MODEL_CODES[model], np.int8) if isinstance(model, str) else np.asarray(model, np.int8)
    data = {"theta": (("config", "param"), theta), "metric": (("config",), np.asarray(outputs["metric"], float)),
            "model": (("config",), codes)}
    for key in ("lateral_um", "longitudinal_um"):
        if key in outputs:
            data[key] = (("config", "tracer"), np.asarray(outputs[key], float))
    if "saturated" in outputs:
        data["steering_mrad"] = (("config",), np.asarray(outputs["steering_mrad"], float))
        data["saturated"] = (("config",), np.asarray(outputs["saturated"], bool))
    ds = xr.Dataset(data, attrs={"identity": json.dumps(identity), "param_labels": json.dumps(list(labels))})
    ds["model"].attrs.update(flag_values=[0, 1], flag_meanings="full reduced")
    path = Path(path)
    if (path / "zarr.json").exists() or (path / ".zgroup").exists():
        ds.to_zarr(path, append_dim="config", consolidated=False)
    else:
        ds.to_zarr(path, mode="w", consolidated=False)


def load_sweep(path: str | Path):
    """The stored Dataset (lazy)."""
    return _xr().open_zarr(Path(path), consolidated=False)
