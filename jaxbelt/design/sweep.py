"""The yield study behind ``jaxbelt sweep``: Monte Carlo in chunks, stored and resumable, with
FORM / importance sampling beside it and a reduced model standing in where it is trusted.

Per chunk of configurations (fixed by the seed, :func:`~jaxbelt.design.sampling.standard_normal_samples`):

1. full model only (``rom="off"``): every configuration runs in full, batched and sharded;
2. ``rom="auto"``: a surrogate (:mod:`jaxbelt.design.surrogate`) is fitted and *validated* on
   separate samples against full runs; it stands in only if its error bound there is below
   10 % of the limit. Then every configuration is predicted by it, and those whose predicted
   metric lies within the bound of the limit are re-run in full (so the pass/fail call of a
   reduced sample is certain up to the bound). Otherwise the sweep falls back to full runs.

Each finished chunk is appended to the Zarr store (``out``), so a rerun resumes.
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np

from .metrics import Study
from .sampling import (Distribution, check_distribution, evaluate_configs, form, importance_sampling,
                       standard_normal_samples, wilson_interval)
from .store import MODEL_CODES, append_chunk, load_sweep, open_sweep

ROM_TRUST_FRACTION = 0.10  # the surrogate's validated error bound must stay below this × limit


def sweep_identity(study: Study, dist: Distribution, n: int, limit_um: float, seed: int, scene: str = "") -> dict:
    return {"scene": scene, "metric": study.metric, "t_eval_s": study.t_eval, "limit_um": float(limit_um),
            "seed": int(seed), "distribution": dist.to_dict(),
            "tracers": int(study.ref_u.shape[1])}


def run_sweep(study: Study, dist: Distribution, n: int, limit_um: float = 20.0, seed: int = 0,
              chunk: int = 64, out=None, rom: str = "off", with_form: bool = True, progress: bool = False,
              scene: str = "", importance_samples: int = 200, rom_method: str = "response") -> dict:
    """Monte-Carlo yield of ``study`` under ``dist`` (module docstring); ``rom_method`` the
    surrogate's reduced model with ``rom="auto"`` (:func:`~jaxbelt.design.surrogate.fit_surrogate`'s
    ``method``: ``"response"`` or ``"pod"``).

    **Returns:** ``{"metric", "limit_um", "samples", "yield", "ci95", "passed", "full_runs",
    "reduced_runs", "rom", "form_yield", "form_beta", "rss_3sigma_um", "is_yield", "is_ci95", "wall_s",
    "configs_per_s", "speedup_estimate", "metric_values" (n,)}`` (``is_*`` only when no or few
    samples failed; ``rss_3sigma_um``: the linear statistical stack-up, ``σ`` of a uniform law
    ``h/√3``; ``speedup_estimate`` with a reduced model: the full model's time per configuration
    in the validation runs, compilation included, times the configurations run, over the wall
    time — indicative, ``benchmarks/yield_rom.py`` measures it side by side)."""
    if not (np.isfinite(limit_um) and limit_um > 0):
        raise ValueError(f"limit_um = {limit_um}: must be a positive number")
    if n < 1:
        raise ValueError(f"samples = {n}: must be at least 1")
    if rom not in ("off", "auto"):
        raise ValueError(f"rom = {rom!r}: one of off, auto")
    if rom_method not in ("response", "pod"):
        raise ValueError(f"rom_method = {rom_method!r}: one of response, pod")
    check_distribution(dist, study)
    t0 = time.perf_counter()
    labels = study.space.labels()
    # jit: one small program instead of compiling norm.cdf's primitives one by one (~2 s)
    thetas = np.asarray(jax.jit(dist.transform)(jnp.asarray(standard_normal_samples(n, study.space.size, seed))))
    identity = sweep_identity(study, dist, n, limit_um, seed, scene)
    done = min(open_sweep(out, identity), n) if out is not None else 0
    metrics, codes = [], []
    if done:
        ds = load_sweep(out)
        metrics.append(np.asarray(ds["metric"].values)[:done])
        codes.append(np.asarray(ds["model"].values)[:done])

    surrogate, rom_info = None, {"used": False}
    if rom == "auto" and done < n:
        from .surrogate import fit_surrogate

        surrogate = fit_surrogate(study, dist, limit_um, seed=seed + 7919, method=rom_method)
        rom_info = dict(surrogate.validation, used=bool(surrogate.bound_um < ROM_TRUST_FRACTION * limit_um))
        if not rom_info["used"]:
            surrogate = None

    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n, initial=done, unit="config", desc="sweep", leave=False)

    def store(theta, outputs, model_codes):
        metrics.append(np.asarray(outputs["metric"]))
        codes.append(model_codes)
        if out is not None:
            append_chunk(out, identity, labels, theta, outputs, model_codes)
        if bar is not None:
            bar.update(len(theta))

    for start in range(done, n, chunk):
        block = thetas[start:start + chunk]
        if surrogate is None:
            res = evaluate_configs(study, block, chunk)
            store(block, res, np.full(len(block), MODEL_CODES["full"], np.int8))
            continue
        res = {k: np.array(v) for k, v in surrogate.evaluate(block).items()}
        near = np.abs(res["metric"] - limit_um) <= res.pop("bound")
        model_codes = np.full(len(block), MODEL_CODES["reduced"], np.int8)
        if np.any(near):
            full = evaluate_configs(study, block[near], chunk)
            for k in res:
                res[k][near] = full[k]
            model_codes[near] = MODEL_CODES["full"]
        store(block, res, model_codes)
    if bar is not None:
        bar.close()
    metric = np.concatenate(metrics) if metrics else np.zeros(0)
    code = np.concatenate(codes) if codes else np.zeros(0, np.int8)
    passed = int(np.sum(metric <= limit_um))
    result = {
        "metric": study.metric, "limit_um": float(limit_um), "samples": int(n), "seed": int(seed),
        "yield": passed / n, "ci95": list(wilson_interval(passed, n)), "passed": passed,
        # the surrogate's training and validation runs are full runs too, used or not
        "full_runs": int(np.sum(code == MODEL_CODES["full"])) + rom_info.get("validation_runs", 0),
        "reduced_runs": int(np.sum(code == MODEL_CODES["reduced"])), "rom": rom_info,
        "metric_values": metric,
    }
    if rom_info["used"] and rom_info.get("n_validation"):
        # indicative: the validation's full runs (their compilation included) per configuration
        per_full = rom_info["validation_s"] / rom_info["n_validation"]
        result["speedup_estimate"] = (n - done) * per_full / max(time.perf_counter() - t0, 1e-9)
    if with_form:
        from .sensitivity import response_jacobian
        from .tolerance import LinearResponse, rss_stackup

        r0, J = response_jacobian(study)
        sigma = [s if k == "normal" else s / np.sqrt(3.0) for k, s in zip(dist.kind, dist.scale)]
        result["rss_3sigma_um"] = rss_stackup(LinearResponse(r0, J, study.aggregate), sigma)["three_sigma_um"]
        f = form(study, dist, limit_um)
        result.update(form_yield=f["yield"], form_beta=f["beta"], form_converged=f["converged"],
                      design_point=study.space.per_roller(f["theta_star"]))
        if n - passed <= max(5, int(0.001 * n)) and f["beta"] > 0:  # yield near 1: MC sees few failures
            i = importance_sampling(study, dist, limit_um, f["u_star"], n=importance_samples, seed=seed + 1,
                                    chunk=chunk)
            result.update(is_yield=i["yield"], is_ci95=list(i["ci95"]), is_samples=i["samples"])
    result["wall_s"] = time.perf_counter() - t0
    result["configs_per_s"] = (n - done) / result["wall_s"]
    return result
