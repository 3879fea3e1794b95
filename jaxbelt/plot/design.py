"""Tolerance design: the sensitivities, the tolerance box and the yield."""

from __future__ import annotations

import numpy as np

from ..infra.results import unit_key
from ._common import finish_figure, pyplot, result_record


def _keys(record):
    """The record's unit (of its metric values) and the function giving a metric-valued entry's key
    (named for µm: ``limit_um``) in it (:func:`jaxbelt.infra.results.unit_key`)."""
    unit = record.get("unit", "µm")
    return unit, lambda name: unit_key(name, unit)


def plot_sensitivity(report, path=None):
    """Bars of the gradient per roller and component (``jaxbelt sensitivity``): translations in
    the metric's unit per mm (µm/mm), rotations per mrad, structurally zero components hatched.
    ``report``: a :class:`~jaxbelt.design.sensitivity.SensitivityReport` (or its ``to_dict()``)."""
    report = result_record(report)
    unit, key_of = _keys(report)
    plt = pyplot()
    rollers = list(report["gradient"])
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    zero = {z["component"] for z in report.get("structural_zero", [])}
    for ax, group, per, comps in ((axes[0], key_of("translation_um_per_mm"), f"{unit}/mm", "xyz"),
                                  (axes[1], key_of("rotation_um_per_mrad"), f"{unit}/mrad", "xyz")):
        width = 0.8 / len(comps)
        for c, axis in enumerate(comps):
            vals = [report["gradient"][r][group][c] for r in rollers]
            pos = np.arange(len(rollers)) + (c - (len(comps) - 1) / 2) * width
            bars = ax.bar(pos, vals, width, label=axis)
            key = ("d" if group.startswith("translation") else "a") + axis
            for b, r in zip(bars, rollers):
                if f"{r}:{key}" in zero:
                    b.set_hatch("//")
        ax.axhline(0, color="k", lw=0.6)
        ax.set_xticks(np.arange(len(rollers)), rollers)
        ax.set_ylabel(f"d {report['metric']} / d misalignment [{per}]")
        ax.set_title("translation" if group.startswith("translation") else "rotation (hatched: no static effect)")
        ax.legend(title="axis")
        ax.grid(alpha=0.3, axis="y")
    when = "in steady operation" if report["t_eval_s"] is None else f"at t = {report['t_eval_s']:.3g} s"
    fig.suptitle(f"{report['metric']} = {report[key_of('value_um')]:.4g} {unit} {when}")
    return finish_figure(fig, path)


def plot_tolerance_box(result, path=None):
    """Half-widths of the tolerance box per component (log scale), binding components marked,
    capped (unconstrained) ones grey; beside it the verification runs against the limit.
    ``result``: a :class:`~jaxbelt.design.tolerance.ToleranceBox`."""
    result = result_record(result)
    unit, key_of = _keys(result)
    plt = pyplot()
    labels, h, units = result["labels"], np.asarray(result["half_widths"]), result["units"]
    binding = set(result["binding"][:3])
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4.5), constrained_layout=True,
                                  gridspec_kw={"width_ratios": [2, 1]})
    colors = ["tab:red" if lab in binding else "tab:grey" if lab in result["unconstrained"] else "tab:blue"
              for lab in labels]
    ax.bar(np.arange(len(h)), h, color=colors)
    ax.set_yscale("log")
    ax.set_xticks(np.arange(len(h)), [f"{lab}\n[{u}]" for lab, u in zip(labels, units)], rotation=60, fontsize=7)
    ax.set_ylabel("half-width (mm or mrad)")
    ax.set_title("tolerance box (red: binding, grey: capped / not felt)")
    ax.grid(alpha=0.3, axis="y")
    rows = result["verification"]
    ax2.scatter([r[key_of("predicted_um")] for r in rows], [r[key_of("full_um")] for r in rows],
                c=["tab:red" if r["kind"] == "worst corner" else "tab:blue" for r in rows])
    lim = result[key_of("limit_um")]
    ax2.axhline(lim, color="k", ls="--", lw=0.8)
    ax2.axhspan(0.97 * lim, lim, color="tab:green", alpha=0.15)
    ax2.plot([0, 1.05 * lim], [0, 1.05 * lim], color="grey", lw=0.6)
    ax2.set_xlabel(f"linear model [{unit}]")
    ax2.set_ylabel(f"full run [{unit}]")
    ax2.set_title("verification (red: worst corners)")
    fig.suptitle(f"{result['metric']} ≤ {lim:g} {unit}: verified worst case {result[key_of('worst_case_um')]:.3f} {unit}")
    return finish_figure(fig, path)


def plot_yield(metric_values, limit_um: float, result, path=None):
    """Histogram of the metric over the Monte-Carlo samples with the limit (both in the result's
    ``unit``, default µm) and the yield. ``result``: a :class:`~jaxbelt.design.sweep.SweepResult`
    (or a mapping with ``yield``, ``ci95``, ``samples`` and ``metric``)."""
    result = result_record(result)
    unit, _ = _keys(result)
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.2), constrained_layout=True)
    ax.hist(np.asarray(metric_values), bins=40, color="tab:blue", alpha=0.8)
    ax.axvline(limit_um, color="tab:red", lw=1.5, label=f"limit {limit_um:g} {unit}")
    lo, hi = result["ci95"]
    ax.set_title(f"yield {result['yield']:.4f} (95 %: {lo:.4f}–{hi:.4f}), {result['samples']} samples")
    ax.set_xlabel(f"{result['metric']} [{unit}]")
    ax.set_ylabel("configurations")
    ax.legend()
    ax.grid(alpha=0.3)
    return finish_figure(fig, path)


