"""mkdocs hooks of jaxbelt's documentation (``mkdocs.yml``: ``hooks``).

* ``readme.md`` is generated from the repository's ``README.md`` (the entry point stays the one
  file), its links to ``docs/…`` pointed at the pages here;
* a link from a page to a repository file outside ``docs/`` — the figures in
  ``benchmarks/results/`` — takes the file into the site at its repository path; a link to any
  other file outside ``docs/`` becomes its path in code (``benchmarks/README.md``), as the site
  holds no copy of it;
* ``<!-- cli-reference -->`` in ``cli.md`` is replaced by :func:`cli_reference.markdown`, the
  reference generated from the argparse parsers;
* ``<!-- solver-registry -->`` in ``scene-format.md``: the names ``[solver]`` accepts, with their
  descriptions and defaults, from ``jaxbelt/registry.py`` (:func:`registry_markdown`);
* ``<!-- reexports -->`` in ``api/jaxbelt.md``: the table of the names ``jaxbelt`` re-exports, each
  linked to its definition;
* ``<!-- decisions -->`` in ``decisions.md`` is replaced by the list of the model decisions, each
  a link to the docstring or the section of ``implementation.md`` that states it
  (:func:`decisions_markdown`);
* ``<!-- benchmark-results -->`` in ``benchmarks.md`` is replaced by one section per
  ``benchmarks/results/*.json``: its values rendered as tables, its PNG and generated Markdown
  beside it (:func:`benchmark_markdown`), so that no measured figure is typed by hand;
* the API pages must cover every module of the packages they document: a module missing from
  them is a warning (an error under ``mkdocs build --strict``).
"""

from __future__ import annotations

import ast
import logging
import os
import posixpath
import re
from pathlib import Path

from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parent.parent
log = logging.getLogger("mkdocs.plugins.jaxbelt")

LINK = re.compile(r"(!?)\[([^\]]*)\]\(([^)\s#]+)(#[^)\s]*)?\)")
IMAGE_EXT = (".png", ".svg", ".jpg", ".jpeg", ".gif")
_extra_files: set[str] = set()


def _docs_dir(config) -> Path:
    return Path(config["docs_dir"]).resolve()


def _page_base(src_uri: str, docs: Path) -> Path:
    """The directory a page's relative links are written against: the repository root for the
    README page, the page's own directory under docs/ otherwise."""
    return ROOT if src_uri == "readme.md" else (docs / src_uri).parent


def _rewrite_links(markdown: str, src_uri: str, docs: Path, collect: set | None = None) -> str:
    base = _page_base(src_uri, docs)

    def fix(m):
        bang, text, target, anchor = m.group(1), m.group(2), m.group(3), m.group(4) or ""
        if re.match(r"^[a-z]+:", target) or target.startswith("/"):
            return m.group(0)
        path = (base / target).resolve()
        if path.is_relative_to(docs) or not path.is_relative_to(ROOT) or not path.exists():
            if src_uri == "readme.md" and path.is_relative_to(docs):
                rel = posixpath.relpath(path.relative_to(docs).as_posix(), posixpath.dirname(src_uri) or ".")
                return f"{bang}[{text}]({rel}{anchor})"
            return m.group(0)  # inside docs/, or a broken link: mkdocs reports it
        repo_rel = path.relative_to(ROOT).as_posix()
        if path.suffix.lower() in IMAGE_EXT:
            if collect is not None:
                collect.add(repo_rel)
            rel = posixpath.relpath(repo_rel, posixpath.dirname(src_uri) or ".")
            return f"{bang}[{text}]({rel}{anchor})"
        return f"{text} (`{repo_rel}`)" if text.strip("`") != repo_rel else f"`{repo_rel}`"

    return LINK.sub(fix, markdown)


def _cli_reference():
    """``scripts/cli_reference.py`` as a module."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("jaxbelt_cli_reference", ROOT / "scripts" / "cli_reference.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def on_files(files, config):
    docs = _docs_dir(config)
    files.append(File.generated(config, "readme.md", content=(ROOT / "README.md").read_text()))
    found: set[str] = set()
    for f in files:
        if f.src_uri.endswith(".md"):
            text = f.content_string if f.generated_by else Path(f.abs_src_path).read_text()
            if BENCHMARK_MARKER in text:
                text = text.replace(BENCHMARK_MARKER, benchmark_markdown())
            _rewrite_links(text, f.src_uri, docs, found)
    for repo_rel in sorted(found):
        files.append(File(repo_rel, str(ROOT), config["site_dir"], config["use_directory_urls"]))
    _extra_files.update(found)
    check_api_coverage(config)
    return files


def on_page_markdown(markdown, page, config, files):
    docs = _docs_dir(config)
    if BENCHMARK_MARKER in markdown:
        markdown = markdown.replace(BENCHMARK_MARKER, benchmark_markdown())
    markdown = _rewrite_links(markdown, page.file.src_uri, docs)
    if "<!-- cli-reference -->" in markdown:
        markdown = markdown.replace("<!-- cli-reference -->", _cli_reference().markdown())
    if "<!-- decisions -->" in markdown:
        markdown = markdown.replace("<!-- decisions -->", decisions_markdown())
    if "<!-- reexports -->" in markdown:
        markdown = markdown.replace("<!-- reexports -->", reexports_markdown())
    if "<!-- solver-registry -->" in markdown:
        markdown = markdown.replace("<!-- solver-registry -->", registry_markdown())
    if "<!-- lateral-skew-table -->" in markdown:
        markdown = markdown.replace("<!-- lateral-skew-table -->", lateral_skew_markdown())
    return markdown


def lateral_skew_markdown(results: Path | None = None) -> str:
    """The skew-walk table of ``lateral.md`` from ``results/lateral_theory.json``: per belt, the
    walk rate of the 2D model and of the two beam loops in units of the string rate."""
    import json

    rows = json.loads(((results or RESULTS) / "lateral_theory.json").read_text())["skew"]
    out = ["| w (mm) | ε₀ | K L | jaxbelt 2D | Timoshenko loop | Euler–Bernoulli loop | 2D vs Timoshenko |",
           "|---|---|---|---|---|---|---|"]
    for r in sorted((r for r in rows if r.get("tension_stiffening", True)), key=lambda r: r["KL"]):
        out.append(f"| {r['width_mm']:g} | {r['eps0']:g} | {r['KL']:.3g} | {r['model_per_string']:.4f} | "
                   f"{r['timoshenko_per_string']:.4f} | {r['euler_bernoulli_per_string']:.4f} | "
                   f"{100 * r['error_vs_timoshenko']:+.2f} % |")
    return "\n".join(out)


def registry_markdown() -> str:
    """Tables of the integrator, linear-solver and transport names of ``jaxbelt/registry.py`` (a
    module that imports nothing, so it is read without importing jaxbelt)."""
    import runpy

    path = ROOT / "jaxbelt" / "registry.py"
    if not path.exists():
        log.warning("jaxbelt/registry.py not found: no table of solver names in scene-format.md")
        return ""
    reg = runpy.run_path(str(path))
    out = []
    for key, table, default in (("integrator", "INTEGRATORS", "DEFAULT_INTEGRATOR"),
                                ("linear_solver", "LINEAR_SOLVERS", "DEFAULT_LINEAR_SOLVER"),
                                ("transport", "TRANSPORT_RULES", "DEFAULT_TRANSPORT")):
        names = reg.get(table, {})
        rows = [[f"`\"{name}\"`" + (" (default)" if name == reg.get(default) else ""), desc.replace("|", "\\|")]
                for name, desc in names.items()]
        out += [f"**`{key}`**", ""] + _table(["value", "what it does"], rows)
    return "\n".join(out) + "\n"


def reexports_markdown() -> str:
    """A table of the names ``jaxbelt/__init__.py`` imports from its modules, each linked to its
    definition."""
    tree = ast.parse((ROOT / "jaxbelt" / "__init__.py").read_text())
    rows = ["| name | defined in |", "|---|---|"]
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module:
            for a in node.names:
                name = a.asname or a.name
                if name.startswith("_"):
                    continue
                target = f"jaxbelt.{node.module}.{a.name}"
                rows.append(f"| `jb.{name}` | [`{target}`][{target}] |")
    return "\n".join(rows) + "\n"


# ----------------------------------------------------------------------------- model decisions


def _docstring_decisions():
    """``(object path, first sentence)`` of every paragraph of a jaxbelt docstring that starts
    with "Decision" (module, class, function and method docstrings)."""
    out = []
    for path in sorted((ROOT / "jaxbelt").rglob("*.py")):
        mod = ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
        if any(part.startswith("_") and part != "__init__" for part in path.relative_to(ROOT).with_suffix("").parts):
            continue
        tree = ast.parse(path.read_text())

        def visit(node, prefix):
            doc = ast.get_docstring(node, clean=True) if isinstance(
                node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) else None
            if doc:
                paras = re.split(r"\n\s*\n", doc)
                for k, para in enumerate(paras):
                    i = para.find("Decision")
                    if i < 0:
                        continue
                    text = " ".join(para[i:].split())
                    if text.endswith(":"):  # a list of decisions follows: their bold lead-ins
                        leads = []
                        for nxt in paras[k + 1:]:
                            found = re.findall(r"^\s*[*-] \*\*(.+?)\*\*", nxt, re.M)
                            if not found:
                                break
                            leads += [lead.rstrip(".:") for lead in found]
                        out.append((prefix, text + " " + "; ".join(leads)))
                        continue
                    first = re.split(r"(?<=\.)\s", text, maxsplit=1)[0]
                    if len(first) > 240:
                        first = first[:240].rsplit(" ", 1)[0] + " …"
                    out.append((prefix, first))
            for child in getattr(node, "body", []):
                if isinstance(child, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and not child.name.startswith("_"):
                    visit(child, f"{prefix}.{child.name}")

        visit(tree, mod)
    return out


DECISIONS_PAGE = "implementation.md"


def _page_decisions():
    """``[(heading, anchor, bold lead-ins)]`` of the bulleted sections of the implementation notes
    (``docs/implementation.md``): every ``## `` section with bullets that start with a bold lead-in."""
    from markdown.extensions.toc import slugify

    text = (ROOT / "docs" / DECISIONS_PAGE).read_text()
    out = []
    for m in re.finditer(r"^## ([^\n]*)\n(.*?)(?=^## |\Z)", text, re.S | re.M):
        heading = m.group(1).strip()
        explicit = re.search(r"\{#([\w-]+)\}\s*$", heading)
        if explicit:
            heading = heading[:explicit.start()].strip()
        anchor = explicit.group(1) if explicit else slugify(heading, "-")
        leads = [lead.rstrip(".:") for lead in re.findall(r"^\* \*\*(.+?)\*\*", m.group(2), re.M)]
        if leads:
            out.append((heading, anchor, leads))
    if not out:
        log.warning(f"docs/{DECISIONS_PAGE}: no bulleted decisions for docs/decisions.md")
    return out


def decisions_markdown() -> str:
    lines = ["## In the docstrings\n", "| where | the decision (its first sentence; follow the link for the reasons) |",
             "|---|---|"]
    for obj, first in _docstring_decisions():
        first = first.replace("|", "\\|")
        lines.append(f'| <autoref identifier="{obj}" optional><code>{obj}</code></autoref> | {first} |')
    lines += ["", "## In the implementation notes\n"]
    for heading, anchor, leads in _page_decisions():
        lines += [f"[{heading}]({DECISIONS_PAGE}#{anchor}):\n"]
        lines += [f"- {lead}" for lead in leads]
        lines.append("")
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- benchmark results

BENCHMARK_MARKER = "<!-- benchmark-results -->"
RESULTS = ROOT / "benchmarks" / "results"

# file stem (or the stem of its script) -> (title, what it measures); every figure comes from the JSON.
BENCHMARKS = {
    "baselines": ("jaxbelt against SciPy SuperLU", "The per-step cost of jaxbelt's exact and reuse steps "
                  "beside SciPy's sparse LU on the same matrix, the whole default run, compilation, `vmap` batches "
                  "and the speedups the source reports, side by side in one run (`jaxbelt bench --only baselines`)."),
    "bending_locking": ("Bending locking of the 2D element", "In-plane bending of a clamped belt strip against "
                        "the Timoshenko beam: the bilinear quad locks when its elements are long and few across, "
                        "the incompatible-modes element (QM6, the default) does not."),
    "steady_state": ("Steady operation solved directly", "The steered design machine's steady state as the fixed "
                     "point of its one-period map (`jaxbelt.steady.steady_state`): Newton steps, residual and time "
                     "per solve, Krylov iterations with and without the mass-transport preconditioner, the design "
                     "tangents' time, aligned and misaligned, beside a time-stepped run of the same noise-free machine, "
                     "when it settles within 0.5 % of a 20 µm limit of the steady deviation, and what those steps "
                     "cost; `solve_with_tangents`: the solve and the 18 tangents in one program "
                     "(`jaxbelt.steady.steady_with_tangents`) against the solve's and the tangents' own programs, "
                     "first call and warm ([tolerance design](tolerance.md#steady-operation))."),
    "call_path": ("How a sweep's study travels through the design package", "The module stops of "
                  "`jaxbelt sweep` on a small scene: every Python call into a `jaxbelt.design` module recorded "
                  "(tracing included), consecutive calls in one module one stop, a stop in a module the path "
                  "had already left a return, a stop whose first call comes from outside its module an entry; "
                  "each stop with the functions it entered, whether it entered and whether it was traced (part of "
                  "building a compiled program); the counts for the whole command and for the sweep itself, "
                  "each with and without the stops under tracing."),
    "design_steady": ("The main job's answer", "`jaxbelt tolerance --json` on the default scene (steady operation, "
                      "error bars on) and on the source's variant `three-roller-tolerance`, as a user runs them; the "
                      "README's table and figures are written from this file (`scripts/readme_results.py`)."),
    "steady_box_check": ("The steady box checked by time-stepping", "The steady tolerance box's worst corner run "
                         "by time-stepping beside the aligned machine until it settles, against the steady solves; "
                         "and the box judged over 16–20 s of a 20 s run (`jaxbelt tolerance --window 4`) for the "
                         "comparison in [tolerance design](tolerance.md#the-steady-box-beside-the-1620-s-window-box)."),
    "closed_loop": ("What the steering loop costs", "A 100 s closed-loop run of `three-roller-steered` against the "
                    "open-loop run of the same machine (its `[[control]]` removed), the same solver and step count, "
                    "best of several runs side by side in one process ([belt steering](steering.md))."),
    "lateral_coarse_mesh": ("Belt walk on coarse meshes", "The skew and twist walk of the two-roller belt at "
                            "K L = 4.9 on 8, 16 and 32 elements per roller arc against the moving-beam reference "
                            "and the per-pass shift ([lateral mechanics](lateral.md))."),
    "accuracy_trade": ("The trade as `--accuracy-um` makes it", "On `three-roller-t72` over 2 s, the true error "
                       "over the last 20 % against the run time of grids around the scene's, and the grids the "
                       "program chooses for 40, 20 and 10 µm ([accuracy on demand](accuracy.md))."),
    "model_choice": ("The cheaper runs an accuracy may take", "The 1D counterpart of the symmetric "
                     "`three-roller` against its 2D run, and float32 against float64 on `three-roller-t72` and "
                     "`two-roller-1d`: the tracer differences and both run times ([accuracy on demand]"
                     "(accuracy.md#the-model-and-the-precision))."),
    "rom_box_sized": ("A reduced model sized to the tolerance", "`jaxbelt reduce three-roller --method dmdc "
                      "--train-ranges BOX.toml --steps 1500` over the 15 free components (±3 mm, ±0.5 mrad), timed "
                      "as its own process with an empty and with a warm compilation cache, its sizing levels, and the "
                      "sized model's error estimate against full runs of fresh configurations from the box "
                      "(effectivity = estimate / true tracer RMSE; [model order reduction](reduction.md))."),
    "dmd_one_run": ("DMD on one configuration", "`jaxbelt reduce three-roller-t72 --method dmd --train-steps 400` "
                    "in one process, with the randomized and with the thin SVD: offline and online time, against "
                    "the fastest full run and against the 400 snapshot steps alone, and the tracer RMSE; then "
                    "snapshots, fit and forecast as one compiled program (`rom.dmd.dmd_forecast`) against the same "
                    "full run ([model order reduction](reduction.md))."),
    "bandwidth_floor": ("The floor of a batched step", "On `three-roller-tolerance` with the reuse solver: the "
                        "bytes a configuration-step streams against the read bandwidth measured in the same process, "
                        "the step, the solve and one sweep's recurrence timed against it for batches of 1, 8 and 32 "
                        "([scale](scale.md#how-fast-a-batch-can-go-on-a-cpu))."),
    "suite_cost": ("Where the test suite's time goes", "Every test in one process, with JAX's compile events "
                   "counted per test (seconds spent tracing, lowering and compiling with XLA against the tests' "
                   "whole time, the programs whose compile took over half a second): the measured cost that sets "
                   "the slow/fast split; then the default test suite (`python -m pytest -q`) as configured (two "
                   "workers) under that split, and the best wall time two workers could reach by splitting the "
                   "default run's one-process work perfectly."),
    "small_time_steps": ("Small time steps and the start-up", "`two-roller-1d` with the idle roller aligned and "
                         "1 mm out, 0.2 s from rest and from a running start at the scene's Δt and Δt/10, /100, "
                         "/1000: the idle roller's speed, the largest tracer displacement and the gap between "
                         "successive levels; and the idle roller's swing after a start from rest against its "
                         "torsional frequency ([small time steps](speed.md#small-time-steps-and-the-start-up))."),
    "tolerance_latency": ("Where the main job's time goes", "`jaxbelt tolerance` on the default design scene, "
                          "stage by stage, in a process with an empty compilation cache and in a second one that "
                          "reads it (there also the verification batch as one `vmap`), then the whole command, "
                          "empty cache and warm, and `jaxbelt steering` and a 1000-sample `jaxbelt sweep` alike. The stage names say which "
                          "question was timed: `aligned_run_and_jacobian_s` the time-stepped 16–20 s window "
                          "(what `--window 4` asks), `aligned_steady_jacobian_and_jitter_s` steady operation; "
                          "the steady path's figures are in [steady operation](#steady_state) and "
                          "[the main job's answer](#design_steady) (`command_s`)."),
    "design_error_bars": ("The design scenes' grids and their error bars", "The tolerance box's worst corner on "
                          "each built-in design scene's grid and one level finer, as a share of the 20 µm limit "
                          "(the rule: at most 5 %), and the half-widths' relative change "
                          "([tolerance design](tolerance.md#error-bars))."),
    "error_estimate": ("The discretisation-error estimate", "Estimated against true error (a run refined 4× in "
                       "every direction) on eleven held-out cases, 1D and 2D, open and closed loop, with and without "
                       "lateral transport: the effectivity and the cost of the estimate in runs of the scene "
                       "([accuracy on demand](accuracy.md))."),
    "design_steered": ("The 20 µm question on the steered machine", "The tolerance box of `three-roller-steered` "
                       "(lateral and longitudinal deviation ≤ 20 µm and the actuator within its range over 16–20 s, "
                       "verified by full closed-loop runs) beside the source's variant `three-roller-tolerance`, and "
                       "the closed-loop gain scan behind the scene's PI gains ([tolerance design](tolerance.md))."),
    "float32": ("float32 against float64", "Tracer error and belt-mass drift of whole runs in single precision "
                "(JAX's default, without `jaxbelt.enable_x64()`) against double precision."),
    "full_run_2d": ("The whole default run", "The 100 s run of `three-roller-t72` (5000 steps) with the reuse solver, "
                    "compilation timed apart, with the process's peak memory."),
    "gpu_2d": ("On a GPU", "Per-step times of the exact solver (block Thomas and block cyclic reduction) and the reuse "
               "solver on an accelerator, and a `vmap` batch of misalignment configurations."),
    "gradient_cost": ("Cost of a gradient", "Reverse-mode gradient of a lateral tracer metric with respect to all "
                      "roller misalignments, through a whole run, against the forward run alone, with and without "
                      "checkpointing."),
    "integrators_1d": ("The 1D integrators", "Per-step cost of the naive, direct and eliminated Backward-Euler "
                       "integrators on the 1D scene, and how far their tracers are from the direct one's."),
    "lateral_theory": ("Belt walk against theory", "Walk rate of a belt on a skewed or twisted roller against the "
                       "loop of moving tensioned beams, over the span parameter K L ([lateral mechanics](lateral.md))."),
    "lateral_span_shape": ("Span shapes in steady walk", "The simulated centre line of both spans during a steady "
                           "walk against the reference's Timoshenko span shapes."),
    "linearity_range": ("Where linearity ends", "The error of the linear prediction of the tracer response against "
                        "the size of each misalignment component."),
    "modal_vs_pod": ("Modal reduction against POD", "The modal reduced integrator beside POD-Galerkin: tracer error "
                     "against the number of modes."),
    "pareto": ("Speed against accuracy", "Tracer error against wall time and memory for grids, time steps, "
               "solvers, float32 and reduced models over the first 20 s of `three-roller-t72`, against a converged "
               "run (`jaxbelt bench --only pareto`)."),
    "pdmd_2d": ("Parametric DMD in 2D", "Parametric DMD over a box of misalignments, trained from the static state "
                "and from after the start-up step."),
    "recompile": ("No recompilation for a new time step or misalignment", "The first call of `simulate` "
                  "(trace, compile, run) against later calls with another time step or another misalignment, "
                  "which run the program already compiled, and the number of XLA compilations each made."),
    "refinement": ("Refinement iterations of the reuse solver", "Time and tracer error of the whole run for 0–3 "
                   "iterative-refinement iterations of the frozen-factor solver, against the exact solver."),
    "rom_1d": ("Reduced models on the 1D scenes", "POD, DMD, DMD with control and parametric DMD on the 1D scenes, "
               "on the training configuration and on a held-out one."),
    "rom_2d": ("Reduced models on the 2D scene", "POD and DMD on `three-roller-t72`, single- and "
               "multi-configuration, with accuracy and total speedups beside the source's."),
    "rom_box_2d": ("One reduced model for every misalignment", "POD and DMD with control trained on an axial design "
                   "over a box of all free misalignment components, tested on configurations with every roller "
                   "misaligned at once."),
    "rom_indicator": ("Error estimate of the reduced models", "The a-posteriori error estimate against the true "
                      "error on held-out configurations (effectivity = estimate / true error)."),
    "scaling_2d": ("Cost against grid size", "Per-step cost of the exact and reuse solvers against the number of "
                   "unknowns, with the fitted log-log slope."),
    "solver_2d": ("The 2D solvers against SciPy", "Per-step cost of the exact solver (block Thomas, cyclic "
                  "reduction) and the reuse solver against a numpy + SciPy SuperLU step."),
    "steering": ("The steering plant against its references", "Steering coefficient against the moving-beam theory "
                 "over the grid, the P loop's boundary against the gain margins, the PI loop holding the belt, and "
                 "the string limit against Shelton's span model ([belt steering](steering.md))."),
    "step_profile": ("Where the time of a step goes", "Assembly, solve, transport and outputs of one step, each "
                     "compiled on its own, for the reuse and exact solvers."),
    "step_vs_superlu": ("Per step against SuperLU, quick", "The two per-step comparisons of the baselines benchmark "
                        "alone, for tracking the machine's state between full runs."),
    "sweep_throughput": ("Sweep throughput", "Configuration-steps per second of the sweep against the batch size, "
                         "exact and reuse solvers."),
    "tension_stiffening_a1": ("What tension stiffening changes", "Tracer differences with and without the "
                              "initial-stress stiffness on the source's Appendix A.1 runs and the tension-roller "
                              "scene."),
    "transport_rules": ("The two transport rules", "The source's relabelling rule and the shift rule against the "
                        "analytic steady strain of a translated idle roller, and their interpolation weights."),
    "tuning": ("Steering-loop tuning against SIMC and Ziegler–Nichols", "PI gains fitted by Adam through the "
               "whole closed-loop run of `two-roller-steered` (GM ≥ 6 dB, PM ≥ 45°), for the ISE and the peak "
               "objective, beside SIMC and Ziegler–Nichols run through the same model, and the gradient in the "
               "gains against central differences ([tuning](tuning.md))."),
    "validation": ("Validation set at fine resolution", "The checks of `tests/integration/test_validation.py` (wave speed, "
                   "statics, lateral translation, convergence, Backward Euler's damping) at resolutions the tests "
                   "cannot afford ([validation](validation.md))."),
    "yield_rom": ("Yield with a reduced model standing in", "A Monte-Carlo yield study with full runs only and with "
                  "the surrogate standing in (`--rom auto`), with the surrogate's error bounds and the pass/fail "
                  "agreement on every sample."),
}

_INLINE_LIST = 8        # lists of at most this many scalars are shown inline
_TABLE_ROWS = 40        # tables of at most this many rows
_TABLE_COLS = 14        # ... and columns
_MAX_DEPTH = 3
_PLAIN_ROWS = 50       # key/value rows per results file, at most
_FILE_LINES = 160      # lines of tables per results file, at most


def _scalar(v) -> bool:
    return v is None or isinstance(v, (bool, int, float, str))


def _fmt(v) -> str:
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if v != v or v in (float("inf"), float("-inf")):
            return str(v)
        if v == 0 or 1e-3 <= abs(v) < 1e5:
            return f"{v:.4g}"
        return f"{v:.3e}"
    if isinstance(v, str):
        return v.replace("|", "\\|").replace("\n", " ")
    return ", ".join(_fmt(x) for x in v)  # a short list of scalars


def _inline(v) -> bool:
    return _scalar(v) or (isinstance(v, list) and len(v) <= _INLINE_LIST and all(_scalar(x) for x in v))


def _flat_dict(v) -> bool:
    return isinstance(v, dict) and bool(v) and all(_inline(x) for x in v.values())


def _table(header, rows) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(row) + " |" for row in rows]
    return out + [""]


def _records_table(records, first=None):
    """A table of flat dicts (the union of their keys as columns), ``first`` naming a leading column
    that holds the dict's keys."""
    cols = []
    for r in records.values() if isinstance(records, dict) else records:
        cols += [k for k in r if k not in cols and _inline(r[k])]
    dropped = len(cols) > _TABLE_COLS
    cols = cols[:_TABLE_COLS]
    header = ([first] if first is not None else []) + [f"`{c}`" for c in cols]
    items = records.items() if isinstance(records, dict) else ((None, r) for r in records)
    rows = [([_fmt(k)] if first is not None else []) + [_fmt(r[c]) if c in r else "" for c in cols]
            for k, r in items]
    out = _table(header, rows)
    if dropped:
        out += ["*(further columns in the JSON file)*", ""]
    return out


def _walk(obj: dict, path: str, depth: int, plain: list, blocks: list, skipped: list):
    for k, v in obj.items():
        key = f"{path}{k}"
        if k == "machine" and not path:
            continue
        if _inline(v):
            plain.append((key, v))
        elif isinstance(v, dict) and v and all(_flat_dict(x) for x in v.values()) and len(v) <= _TABLE_ROWS:
            blocks.append([f"**`{key}`**", ""] + _records_table(v, first=""))
        elif isinstance(v, list) and v and all(_flat_dict(x) for x in v) and len(v) <= _TABLE_ROWS:
            blocks.append([f"**`{key}`**", ""] + _records_table(v))
        elif isinstance(v, dict) and v and depth < _MAX_DEPTH:
            _walk(v, f"{key}.", depth + 1, plain, blocks, skipped)
        else:
            skipped.append(f"`{key}` ({len(v)} entries)" if isinstance(v, (list, dict)) else f"`{key}`")


def _render(obj: dict, budget: int = _FILE_LINES) -> list[str]:
    """Markdown for one JSON object: its inline values (nested keys dotted) as one key/value table,
    then a table per list or dict of records; what does not fit is named, not shown."""
    plain, blocks, skipped = [], [], []
    _walk(obj, "", 0, plain, blocks, skipped)
    shown = plain[:_PLAIN_ROWS]
    out = _table(["key", "value"], [[f"`{k}`", _fmt(v)] for k, v in shown]) if shown else []
    if len(plain) > len(shown):
        out += [f"*… and {len(plain) - len(shown)} more values in the JSON file.*", ""]
    for i, block in enumerate(blocks):
        if len(out) + len(block) > budget:
            skipped += [b[0].strip("*") for b in blocks[i:]]
            break
        out += block
    if skipped:
        names = ", ".join(skipped[:10]) + (f" and {len(skipped) - 10} more" if len(skipped) > 10 else "")
        out += [f"*Not shown here (see the JSON file):* {names}.", ""]
    return out


def _machine(d) -> str:
    m = d.get("machine") if isinstance(d, dict) else None
    if not isinstance(m, dict):
        return ""
    parts = [f"{k} {m[k]}" for k in ("device", "cpu_count", "jax", "python", "openblas_num_threads") if k in m]
    return "Measured on: " + ", ".join(parts).replace("cpu_count", "CPUs") + "." if parts else ""


def _benchmark_key(stem: str) -> str:
    """The ``BENCHMARKS`` entry of a results file: its stem, or the stem with its last ``_part``
    dropped (``full_run_2d_gpu`` → ``full_run_2d``, ``rom_2d_quick`` → ``rom_2d``)."""
    key = stem
    while key not in BENCHMARKS and "_" in key:
        key = key.rsplit("_", 1)[0]
    return key if key in BENCHMARKS else stem


def benchmark_markdown(results: Path = RESULTS) -> str:
    """One section per ``results/*.json``: title and lead from :data:`BENCHMARKS`, the script that
    writes it, the machine, the values as tables, the PNG and a generated ``.md`` of the same stem."""
    import json

    out = []
    stems = sorted(p.stem for p in results.glob("*.json"))
    seen: dict[str, int] = {}
    for stem in stems:
        key = _benchmark_key(stem)
        title, lead = BENCHMARKS.get(key, (stem.replace("_", " "), ""))
        n = sum(_benchmark_key(s) == key for s in stems)
        seen[key] = seen.get(key, 0) + 1
        anchor = key if seen[key] == 1 else f"{key}-{seen[key]}"
        suffix = stem[len(key):].lstrip("_")
        if n == 1 or not suffix:
            label = ""
        elif re.fullmatch(r"[0-9a-f]{7,40}", suffix):  # a run labelled by the version it measured
            label = f" (run {sorted(s for s in stems if _benchmark_key(s) == key).index(stem) + 1})"
        else:
            label = f" ({suffix.replace('_', ' ')})"
        out += [f"## {title}{label} {{#{anchor}}}", ""]
        script = ROOT / "benchmarks" / f"{key}.py"
        made = f"Written by `python benchmarks/{key}.py`" if script.exists() else "Written by a benchmark script"
        out += [(lead + " " if lead else "") + f"{made} to [{stem}.json](../benchmarks/results/{stem}.json).", ""]
        try:
            data = json.loads((results / f"{stem}.json").read_text())
        except ValueError as e:
            log.warning(f"benchmarks/results/{stem}.json: {e}")
            continue
        machine = _machine(data)
        if machine:
            out += [machine, ""]
        out += _render(data) if isinstance(data, dict) else [f"*({type(data).__name__} of {len(data)} entries)*", ""]
        if (results / f"{stem}.md").exists():
            out += [(results / f"{stem}.md").read_text().strip(), ""]
        if (results / f"{stem}.png").exists():
            out += [f"![{title}](../benchmarks/results/{stem}.png)", ""]
    return "\n".join(out) + "\n"


# ----------------------------------------------------------------------------- API coverage


def check_api_coverage(config):
    """Warn about a module of a documented package that no API page renders."""
    docs = _docs_dir(config)
    rendered = set()
    for md in (docs / "api").glob("*.md"):
        rendered |= set(re.findall(r"^::: ([\w.]+)", md.read_text(), re.M))
    packages = {r.rsplit(".", 1)[0] for r in rendered if r.count(".") >= 2} | {
        r for r in rendered if (ROOT / r.replace(".", os.sep) / "__init__.py").exists()}
    for pkg in sorted(packages):
        pdir = ROOT / pkg.replace(".", os.sep)
        if not (pdir / "__init__.py").exists() or pkg == "jaxbelt":
            continue
        for f in sorted(pdir.glob("*.py")):
            if f.name.startswith("_"):
                continue
            name = f"{pkg}.{f.stem}"
            if name not in rendered:
                log.warning(f"API pages: module {name} is not documented (add '::: {name}' to a page in docs/api/)")
