"""mkdocs hooks of jaxbelt's documentation (``mkdocs.yml``: ``hooks``).

* ``readme.md`` is generated from the repository's ``README.md`` (the entry point stays the one
  file), its links to ``docs/…`` pointed at the pages here;
* a link from a page to a repository file outside ``docs/`` — the figures in
  ``benchmarks/results/`` — takes the file into the site at its repository path; a link to any
  other file outside ``docs/`` becomes its path in code (``benchmarks/README.md``), as the site
  holds no copy of it;
* ``<!-- cli-reference -->`` in ``cli.md`` is replaced by :func:`cli_reference.markdown`, the
  reference generated from the argparse parsers;
* ``<!-- reexports -->`` in ``api/jaxbelt.md``: the table of the names ``jaxbelt`` re-exports, each
  linked to its definition;
* ``<!-- decisions -->`` in ``decisions.md`` is replaced by the list of the model decisions, each
  a link to the docstring or README section that states it (:func:`decisions_markdown`);
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
            _rewrite_links(text, f.src_uri, docs, found)
    for repo_rel in sorted(found):
        files.append(File(repo_rel, str(ROOT), config["site_dir"], config["use_directory_urls"]))
    _extra_files.update(found)
    check_api_coverage(config)
    return files


def on_page_markdown(markdown, page, config, files):
    docs = _docs_dir(config)
    markdown = _rewrite_links(markdown, page.file.src_uri, docs)
    if "<!-- cli-reference -->" in markdown:
        markdown = markdown.replace("<!-- cli-reference -->", _cli_reference().markdown())
    if "<!-- decisions -->" in markdown:
        markdown = markdown.replace("<!-- decisions -->", decisions_markdown())
    if "<!-- reexports -->" in markdown:
        markdown = markdown.replace("<!-- reexports -->", reexports_markdown())
    return markdown


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


def _readme_decisions():
    """The bold lead-ins of the bullets under the README's decisions heading, with the anchor."""
    text = (ROOT / "README.md").read_text()
    m = re.search(r"^## (The model, and the decisions[^\n]*)\n(.*?)(?=^## )", text, re.S | re.M)
    if not m:
        log.warning("README.md: no section 'The model, and the decisions …' for docs/decisions.md")
        return "", []
    from markdown.extensions.toc import slugify

    anchor = slugify(m.group(1), "-")
    return anchor, re.findall(r"^\* \*\*(.+?)\*\*", m.group(2), re.M)


def decisions_markdown() -> str:
    lines = ["## In the docstrings\n", "| where | the decision (its first sentence; follow the link for the reasons) |",
             "|---|---|"]
    for obj, first in _docstring_decisions():
        first = first.replace("|", "\\|")
        lines.append(f'| <autoref identifier="{obj}" optional><code>{obj}</code></autoref> | {first} |')
    anchor, leads = _readme_decisions()
    lines += ["", "## In the README\n",
              f"[The model, and the decisions where the source and MODEL.md are silent](readme.md#{anchor}):\n"]
    lines += [f"- {lead.rstrip('.:')}" for lead in leads]
    return "\n".join(lines) + "\n"


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
