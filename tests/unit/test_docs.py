"""The generated parts of the documentation (``scripts/``): the CLI reference lists every command
and option of the parsers, docstring roles become cross-references, the model decisions are
found, the benchmarks page renders every results file, the solver names come from the registry,
and citations of the model specification resolve. (``mkdocs build --strict`` itself runs in
``.ci/run``.)"""

import argparse
import importlib.util
import json
import re

import pytest
from helpers import REPO

ROOT = REPO
SCRIPTS = ROOT / "scripts"
DOCS = ROOT / "docs"


def _load(name):
    spec = importlib.util.spec_from_file_location(f"jaxbelt_docs_{name}", SCRIPTS / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_cli_reference_lists_every_command_and_option():
    from jaxbelt.cli import build_parser

    md = _load("cli_reference").markdown()
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    for name, p in sub.choices.items():
        section = md.split(f"`jaxbelt {name}` {{#jaxbelt-{name}}}", 1)[1].split("\n## ", 1)[0]
        for a in p._actions:
            for opt in a.option_strings:
                if opt not in ("-h", "--help"):
                    assert f"`{opt}`" in section, (name, opt)
    assert "`--plot-fields`" in md and "`--field-times`" in md


def test_docstring_roles_and_lists():
    pytest.importorskip("griffe")
    convert = _load("griffe_docstrings").convert
    out = convert("**Arguments:**\n- ``m``: :class:`~jaxbelt.Mesh`, :func:`jaxbelt.simulate`\n\n```\n:func:`x`\n```")
    assert out.splitlines()[1] == ""  # the list gets its blank line
    assert '<autoref identifier="jaxbelt.Mesh" optional><code>Mesh</code></autoref>' in out
    assert "<code>jaxbelt.simulate</code>" in out and ":func:`x`" in out  # code blocks untouched


def test_decisions_are_collected():
    pytest.importorskip("mkdocs")
    hooks = _load("mkdocs_hooks")
    found = dict(hooks._docstring_decisions())
    assert "jaxbelt.transport" in found and "Roller arcs" in found["jaxbelt.transport"]
    assert "jaxbelt.prestress.slack_spans" in found
    sections = {heading: (anchor, leads) for heading, anchor, leads in hooks._page_decisions()}
    anchor, leads = sections["Decisions of the model"]
    assert anchor == "decisions" and any("Transport relabelling" in x for x in leads)
    assert any("Tension stiffening" in x for x in sections["The 2D model"][1])
    md = hooks.decisions_markdown()
    assert "(implementation.md#decisions)" in md and "- Transport relabelling" in md


def _hooks():
    pytest.importorskip("mkdocs")
    return _load("mkdocs_hooks")


def test_benchmark_page_renders_every_results_file():
    hooks = _hooks()
    results = ROOT / "benchmarks" / "results"
    md = hooks.benchmark_markdown()
    stems = sorted(p.stem for p in results.glob("*.json"))
    anchors = re.findall(r"^## .*\{#([\w-]+)\}$", md, re.M)
    assert len(anchors) == len(stems) == len(set(anchors))
    for stem in stems:
        assert f"[{stem}.json](../benchmarks/results/{stem}.json)" in md
        assert (f"(../benchmarks/results/{stem}.png)" in md) == (results / f"{stem}.png").exists()
        assert hooks._benchmark_key(stem) in hooks.BENCHMARKS, (
            f"benchmarks/results/{stem}.json: add a title and a lead sentence to BENCHMARKS in scripts/mkdocs_hooks.py")
    assert (DOCS / "benchmarks.md").read_text().count(hooks.BENCHMARK_MARKER) == 1


def test_benchmark_tables_render_values_generically(tmp_path):
    hooks = _hooks()
    data = {"machine": {"device": "cpu:0", "cpu_count": 2, "jax": "0.0"}, "scene": "three-roller", "n": 3762,
            "ms": 0.123456, "ok": True, "ranks": [5, 10, 20], "huge": list(range(500)),
            "rows": {"exact": {"ms": 1.5, "err": 1e-13}, "reuse": {"ms": 0.5, "err": 2e-14}},
            "cases": [{"w_mm": 50, "rate": 0.62}, {"w_mm": 5, "rate": 0.96}], "nested": {"a": {"b": 7}, "c": 1}}
    (tmp_path / "toy_bench.json").write_text(json.dumps(data))
    (tmp_path / "toy_bench.png").write_bytes(b"")
    md = hooks.benchmark_markdown(tmp_path)
    assert "## toy bench {#toy_bench}" in md and "Measured on: device cpu:0, CPUs 2, jax 0.0." in md
    for row in ("| `scene` | three-roller |", "| `n` | 3762 |", "| `ms` | 0.1235 |", "| `ok` | yes |",
                "| `ranks` | 5, 10, 20 |", "| `nested.a.b` | 7 |", "| `nested.c` | 1 |", "| exact | 1.5 | 1.000e-13 |", "| 50 | 0.62 |"):
        assert row in md, row
    assert "`huge` (500 entries)" in md and "0, 1, 2, 3" not in md
    assert "![toy bench](../benchmarks/results/toy_bench.png)" in md


def test_solver_names_come_from_the_registry():
    hooks = _hooks()
    from jaxbelt import registry

    md = hooks.registry_markdown()
    for table in (registry.INTEGRATORS, registry.LINEAR_SOLVERS, registry.TRANSPORT_RULES):
        for name in table:
            assert f'`"{name}"`' in md, name
    assert f'`"{registry.DEFAULT_LINEAR_SOLVER}"` (default)' in md
    assert "<!-- solver-registry -->" in (DOCS / "scene-format.md").read_text()


def test_model_specification_sections_and_citations():
    """docs/model.md keeps the specification's numbering (§1 … §8) with a ``model-n`` anchor per
    section, and docstring citations of a section become links to it."""
    pytest.importorskip("griffe")
    text = (DOCS / "model.md").read_text()
    numbers = [int(n) for n in re.findall(r"^## (\d+)\. ", text, re.M)]
    assert numbers == list(range(1, len(numbers) + 1)) and len(numbers) >= 8
    for n in numbers:
        assert re.search(rf"^\[\]\(\){{#model-{n}}}\n\n## {n}\. ", text, re.M), n
    links = _load("griffe_docstrings").spec_links
    assert links("Unknowns (MODEL.md §2, §4).") == "Unknowns ([model specification §2][model-2], [§4][model-4])."
    assert links("(§3.3, MODEL.md §2–§4)") == "(§3.3, [model specification §2][model-2]–[§4][model-4])"
    assert links("the model specification §6 and §4.2") == "the [model specification §6][model-6] and §4.2"
    assert links("MODEL.md §4.2") == "MODEL.md §4.2"  # a subsection of the source is not the specification's


def test_links_into_the_readme_point_at_its_headings():
    """Pages may link README sections (``readme.md#…``, the generated page): only ones that exist."""
    from markdown.extensions.toc import slugify

    headings = re.findall(r"^#+ (.+)$", re.sub(r"^```.*?^```", "", (ROOT / "README.md").read_text(), flags=re.S | re.M),
                          re.M)
    slugs = {slugify(h, "-") for h in headings}
    sources = [*DOCS.rglob("*.md"), *SCRIPTS.glob("*.py"), *(ROOT / "jaxbelt").rglob("*.py")]
    for path in sources:
        for anchor in re.findall(r"readme\.md#([\w-]+)", path.read_text(), re.I):
            assert anchor in slugs, f"{path.relative_to(ROOT)}: readme.md#{anchor} is not a README heading"


def test_scene_format_lists_every_builtin_scene():
    """docs/scene-format.md names every built-in scene; the tables' numbered variants (``-t73-test1..6``,
    ``-a1-run1..12``) and the 1D scene's suffixed variants by family."""
    import jaxbelt as jb

    text = (DOCS / "scene-format.md").read_text()
    families = ("three-roller-t7", "three-roller-a1-run", "two-roller-1d-")
    missing = [n for n in jb.builtin_scene_names() if f"`{n}`" not in text and not n.startswith(families)]
    assert not missing, missing
