"""The generated parts of the documentation (``scripts/``): the CLI reference lists every command
and option of the parsers, docstring roles become cross-references, the model decisions are
found. (``mkdocs build --strict`` itself runs in ``.ci/run``.)"""

import argparse
import importlib.util
from pathlib import Path

import pytest

SCRIPTS = Path(__file__).resolve().parent.parent / "scripts"


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
    anchor, leads = hooks._readme_decisions()
    assert anchor.startswith("the-model-and-the-decisions") and any("Transport relabelling" in x for x in leads)
