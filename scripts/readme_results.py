"""The README's answer to the 20 µm question, generated from ``benchmarks/results/design_steady.json``
(and docs/tolerance.md's comparison of the steady box with the window box, from
``steady_box_check.json``; docs/speed.md's figures of what the design commands cost, from
``tolerance_latency.json`` and ``steady_state.json``).

``benchmarks/design_steady.py`` runs the main job (``jaxbelt tolerance --json`` on the default
scene, and on the source's variant ``three-roller-tolerance``) and keeps both outputs; this script
writes the README block between ``<!-- results:begin -->`` and ``<!-- results:end -->`` from them:
the table of half-widths and every figure of the prose around it. ``python
scripts/readme_results.py`` rewrites the block; ``--check`` exits 1 if the README differs from what
it would write (the test suite runs the same comparison), so the front door cannot drift from the
results.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "design_steady.json"
CHECK = ROOT / "benchmarks" / "results" / "steady_box_check.json"
README = ROOT / "README.md"
TOLERANCE_DOC = ROOT / "docs" / "tolerance.md"
BEGIN, END = "<!-- results:begin -->", "<!-- results:end -->"
STEERED, SOURCE = "three-roller-steered", "three-roller-tolerance"


def _cells(box: dict, name: str, unconstrained: set) -> tuple[str, str]:
    """``x/y/z µm`` and ``about x/y µrad`` of one roller; ``–`` where a component is not felt."""
    t = [(f"{name}:d{a}", v * 1e3) for a, v in zip("xyz", box[name]["translation_mm"])]
    r = [(f"{name}:a{a}", v * 1e3) for a, v in zip("xy", box[name]["rotation_mrad"][:2])]
    fmt = lambda kv: "–" if kv[0] in unconstrained else f"{kv[1]:.3g}"  # noqa: E731
    return "/".join(map(fmt, t)), "/".join(map(fmt, r))


def _limit(res: dict, metric: str) -> dict:
    return next(x for x in res["limits"] if x["metric"] == metric)


def render(data: dict) -> str:
    """The README block (without its markers) from the results."""
    st, so = data[STEERED], data[SOURCE]
    rows = []
    for name in st["box"]:
        a = _cells(st["box"], name, set(st["unconstrained"]))
        b = _cells(so["box"], name, set(so["unconstrained"]))
        rows.append(f"| {name} | {a[0]} | {a[1]} | {b[0]} | {b[1]} |")
    lat, lon, steer = (_limit(st, m) for m in ("lateral_max", "longitudinal_max", "steering_max"))
    binds = {"lateral_max": "lateral", "longitudinal_max": "longitudinal (registration)",
             "steering_max": "actuator-range"}[st["binding_limit"]]
    actuated = data["actuated_component"]
    h_act = next(r["half_width"] for r in st["half_widths"] if r["component"] == actuated)
    jitter = max(st["actuator_jitter_mrad"])
    return "\n".join([
        "| roller | steered: x/y/z µm | steered: about x/y µrad | source: x/y/z µm | source: about x/y µrad |",
        "|---|---|---|---|---|",
        *rows,
        "",
        f"On the steered machine the {binds} limit binds: the verified worst corners reach "
        f"{lat['worst_case']:.3g} µm lateral and {lon['worst_case']:.3g} µm longitudinal deviation, and the "
        f"actuator {steer['worst_case']:.3g} of its {steer['limit']:g} mrad (its own jitter from sensor noise and "
        f"the edge's waviness, {jitter:.3g} mrad, included). The steering roller's own tilt about its actuated "
        f"axis ({actuated}) costs no deviation at all in steady operation — the loop takes it out completely — "
        f"so only the actuator's range limits it: ±{h_act * 1e3:.4g} µrad.",
    ])


def render_comparison(data: dict, check: dict) -> str:
    """docs/tolerance.md's block: the steady box beside the 16–20 s window box, and the steady
    box's worst corner by steady solves beside a time-stepped run that settles."""
    st, win = data[STEERED], check["window_box"]
    wh = {r["component"]: r for r in win["half_widths"]}
    rows = ["| component | steady | 16–20 s window | unit |", "|---|---|---|---|"]
    for r in st["half_widths"]:
        w = wh[r["component"]]
        fmt = lambda row, res: "–" if row["component"] in res["unconstrained"] else f"{row['half_width'] * 1e3:.3g}"  # noqa: E731
        unit = "µm" if r["unit"] == "mm" else "µrad"
        rows.append(f"| {r['component']} | {fmt(r, st)} | {fmt(w, win)} | {unit} |")
    last = check["time_stepped_blocks"][-1]
    by = check["steady_by_limit"]
    binds = lambda res: res["binding_limit"]  # noqa: E731
    rows += ["", f"Binding limit: {binds(st)} in steady operation, {binds(win)} over the window. At the steady box's "
             f"worst corner the steady solves read {by['lateral_max']:.4g} µm lateral, {by['longitudinal_max']:.4g} µm "
             f"longitudinal deviation and {by['steering_max']:.4g} mrad of actuator (jitter included); a time-stepped "
             f"run of that corner beside the aligned machine (same sensor seed), {last['t_end_s']:g} s long, reads "
             f"{last['lateral_max_um']:.4g} µm, {last['longitudinal_max_um']:.4g} µm and "
             f"{last['steering_max_mrad']:.4g} mrad over its last {WINDOW_S:g} s"
             + (f", its last two {BLOCK_S:g} s blocks agreeing within {check['settled_within_um']:.3g} µm."
                if check["settled"] else ", not yet settled within the runs made.")]
    blocks = check["time_stepped_blocks"]
    first = blocks[0]
    back = next((b["t_end_s"] for b in blocks if b["lateral_max_um"] <= st["limit_um"]), None)
    rows[-1] += (f" The start from rest is a transient question (`--window`), and a different answer: over "
                 f"{BLOCK_S - WINDOW_S:g}–{BLOCK_S:g} s this corner's belt runs up to {first['lateral_max_um']:.4g} µm off its path with "
                 f"the actuator at {first['steering_max_mrad']:.4g} mrad, and its lateral deviation is within the "
                 f"{st['limit_um']:g} µm limit again only in the {WINDOW_S:g} s before "
                 + (f"{back:g} s." if back is not None else "the end of the last block run."))
    return "\n".join(rows)


WINDOW_S, BLOCK_S = 4.0, 20.0
DOC_BEGIN, DOC_END = "<!-- steady-vs-window:begin -->", "<!-- steady-vs-window:end -->"


LATENCY = ROOT / "benchmarks" / "results" / "tolerance_latency.json"
STEADY = ROOT / "benchmarks" / "results" / "steady_state.json"
SPEED_DOC = ROOT / "docs" / "speed.md"
COST_BEGIN, COST_END = "<!-- design-cost:begin -->", "<!-- design-cost:end -->"


def _span(values, fmt: str) -> str:
    lo, hi = format(min(values), fmt), format(max(values), fmt)
    return lo if lo == hi else f"{lo}–{hi}"


def render_costs(lat: dict, ss: dict) -> str:
    """docs/speed.md's figures of what the design commands cost, from ``tolerance_latency.json``
    and ``steady_state.json``."""
    c, o = lat["command"], lat["other_commands"]
    eb, nb = c["error_bars"], c["no_error_bars"]
    runs = eb.get("warm_cache_runs_s") or [eb["warm_cache_s"]]
    warm_runs = (f"median of {len(runs)} warm runs, {_span(runs, '.1f')} s; " if len(runs) > 1 else "")
    cold, warm = lat["empty_cache"]["stages"], lat["warm_cache"]["stages"]
    cases, t, w = ss["cases"], ss["tangents"], ss["solve_with_tangents"]
    steps = [r["newton_steps"] for r in cases]
    its = [r["krylov_iterations"] for r in cases]
    plain = [r["unpreconditioned"]["krylov_iterations"] for r in cases]
    solve = [r["solve_warm_s"] for r in cases]
    sw, swn = o["sweep_1000"], o["sweep_1000_no_error_bars"]
    return "\n".join([
        f"On the default design scene (`{lat['empty_cache']['scene']}`, N = {lat['empty_cache']['n_unknowns']}, "
        f"this 2-core machine; [measured](benchmarks.md#tolerance_latency)): `jaxbelt tolerance` takes "
        f"{eb['empty_cache_s']:.0f} s with an empty compilation cache and {eb['warm_cache_s']:.1f} s with a warm "
        f"one ({warm_runs}error bars on; {nb['empty_cache_s']:.0f} s and {nb['warm_cache_s']:.1f} s without "
        f"them), `jaxbelt steering` {o['steering']['empty_cache_s']:.0f} s and {o['steering']['warm_cache_s']:.1f} s, "
        f"a 1000-sample `jaxbelt sweep` {sw['empty_cache_s']:.0f} s and {sw['warm_cache_s']:.0f} s "
        f"({swn['empty_cache_s']:.0f} s and {swn['warm_cache_s']:.0f} s without its error bar).",
        "",
        f"A steady solve is Newton's method with GMRES on the linearised period map ({_span(steps, 'd')} Newton "
        f"steps, {_span(its, 'd')} Krylov iterations of one linearised period each, {_span(plain, 'd')} without the "
        f"mass-transport preconditioner; {_span(solve, '.2f')} s per solve on the design scene; "
        "[Steady operation](tolerance.md#steady-operation) says why, [measured](benchmarks.md#steady_state)). "
        f"The aligned machine's steady state with its {w['parameters']} derivatives is one program (Newton's steps, "
        "then one tangent solve per component, on one linearisation of the period map): "
        f"{w['one_program_s']:.2f} s, against {w['solve_s'] + w['tangents_s']:.2f} s for the solve and a separate "
        f"tangent program, and {w['one_program_first_s']:.0f} s to compile and run it the first time, against "
        f"{w['solve_first_s'] + w['tangents_first_s']:.0f} s for the two "
        f"({t['through_the_solve_s']:.2f} s differentiating through the solve instead). In a warm process the tolerance box's own arithmetic is a few seconds: the "
        "aligned steady state, its derivatives and the actuator jitter's run "
        f"{warm['aligned_steady_jacobian_and_jitter_again_s']:.1f} s, the verification solves and the box search "
        f"{warm['tolerance_box_s']:.1f} s, the finer grid's solves of the error bars {warm['error_bars_s']:.1f} s. "
        f"What a warm command spends beyond that is fixed cost: {warm['imports_s']:.1f} s of imports, "
        f"{warm['model_build_s'] + warm['finer_model_build_s']:.1f} s for the two grids' model builds, and loading "
        "the compiled programs from the cache (the aligned machine's programs take "
        f"{warm['aligned_steady_jacobian_and_jitter_s']:.1f} s on their first call, "
        f"{warm['aligned_steady_jacobian_and_jitter_again_s']:.1f} s on the second). With an empty cache most of "
        "the time is XLA compiling: the aligned machine's steady program and the jitter's run "
        f"{cold['aligned_steady_jacobian_and_jitter_s']:.0f} s (with their tracing and first run), the finer grid's "
        f"error bars {cold['error_bars_s']:.0f} s; the verification solves reuse the compiled program "
        f"({cold['verification_batch_first_s']:.1f} s for eight of them, the first time).",
    ])


def block(text: str, begin: str = BEGIN, end: str = END) -> str:
    """A file's current block between the markers."""
    i, j = text.index(begin) + len(begin), text.index(end)
    return text[i:j].strip("\n")


def _replace(path: Path, new: str, begin: str, end: str) -> bool:
    text = path.read_text()
    if block(text, begin, end) == new:
        return False
    i, j = text.index(begin) + len(begin), text.index(end)
    path.write_text(text[:i] + "\n" + new + "\n" + text[j:])
    return True


def expected() -> dict:
    """``{(path, begin, end): block}`` for every generated block."""
    data = json.loads(RESULTS.read_text())
    return {(README, BEGIN, END): render(data),
            (TOLERANCE_DOC, DOC_BEGIN, DOC_END): render_comparison(data, json.loads(CHECK.read_text())),
            (SPEED_DOC, COST_BEGIN, COST_END): render_costs(json.loads(LATENCY.read_text()),
                                                            json.loads(STEADY.read_text()))}


def write() -> bool:
    """Rewrite every block; ``True`` if one changed."""
    return any([_replace(p, new, b, e) for (p, b, e), new in expected().items()])


if __name__ == "__main__":
    if "--check" in sys.argv[1:]:
        same = all(block(p.read_text(), b, e) == new for (p, b, e), new in expected().items())
        print("README and docs match the results" if same else "they differ from the results: run scripts/readme_results.py")
        sys.exit(0 if same else 1)
    print("README and docs rewritten" if write() else "README and docs already match the results")
