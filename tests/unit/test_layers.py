"""The package's layers hold: no module imports a private name of another module, and the
import-linter contracts (``pyproject.toml``, run by ``lint-imports``) are kept."""

import ast
import subprocess
import sys
from pathlib import Path

from helpers import REPO

PACKAGE = REPO / "jaxbelt"


def private_name_imports(package: Path = PACKAGE) -> list[str]:
    """``file:line: from X import _name`` for every import of a private name (one underscore)
    from another module."""
    hits = []
    for path in sorted(package.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                for alias in node.names:
                    if alias.name.startswith("_") and not alias.name.startswith("__"):
                        hits.append(f"{path.relative_to(package)}:{node.lineno}: "
                                    f"from {'.' * node.level}{node.module or ''} import {alias.name}")
    return hits


def test_no_private_names_imported_across_modules():
    assert private_name_imports() == []


def test_the_scanner_finds_a_private_import(tmp_path):
    (tmp_path / "a.py").write_text("from .b import _hidden\nfrom .b import public\n")
    assert private_name_imports(tmp_path) == ["a.py:1: from .b import _hidden"]


def test_import_contracts_are_kept():
    """The contracts run through this interpreter's import-linter (a test dependency): a missing
    linter fails here instead of skipping the contracts unnoticed."""
    code = "import sys; from importlinter.cli import lint_imports; sys.exit(lint_imports())"
    out = subprocess.run([sys.executable, "-c", code], cwd=PACKAGE.parent, capture_output=True, text=True)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-2000:]
