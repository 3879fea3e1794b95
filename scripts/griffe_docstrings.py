"""Griffe extension for jaxbelt's API pages (``mkdocs.yml``: mkdocstrings ``extensions``).

jaxbelt's docstrings are Markdown with a few reStructuredText habits; this turns them into what
mkdocstrings renders well, for the docs only (the source is not changed):

* Sphinx roles ``:func:`~jaxbelt.simulate``` (also ``:class:``, ``:meth:``, ``:mod:``, ``:data:``,
  ``:attr:``, ``:exc:``) become optional cross-references (``<autoref … optional>``): a link
  where the target is on an API page (re-exports resolved to their definition, bare names to
  the object's own module), plain code where it is not (no warning);
* a list or table that follows a text line directly gets the blank line Python-Markdown needs;
* a section of the model specification cited as ``MODEL.md §4``, ``docs/model.md §4`` or
  ``model specification §4`` (also ``§2–§4``, ``§2, §4``) becomes a link to that section of
  ``docs/model.md`` (its ``[](){#model-4}`` anchors).
"""

from __future__ import annotations

import re

import griffe

ROLE = re.compile(r":(?:func|class|meth|mod|data|attr|exc|obj):`(~?)([\w.]+)(?:\(\))?`")
BLOCK_START = re.compile(r"^\s*(?:[-*] |\d+\. |\|)")
SPEC = re.compile(r"(?:MODEL\.md|docs/model\.md|model specification(?: \(docs/model\.md\))?),?\s*"
                  r"§\s*(\d+)(?!\.?\d)((?:\s*(?:,|and|–|-)\s*§\s*\d+(?!\.?\d))*)")


def spec_links(line: str) -> str:
    """Citations of the model specification's sections as links to ``docs/model.md``."""

    def link(m):
        first = f"[model specification §{m.group(1)}][model-{m.group(1)}]"
        rest = re.sub(r"§\s*(\d+)", lambda k: f"[§{k.group(1)}][model-{k.group(1)}]", m.group(2))
        return first + rest

    return SPEC.sub(link, line)


def _resolve(collection, identifier: str, context) -> str:
    candidates = [identifier]
    if context is not None:
        mod = context.module if not context.is_module else context
        candidates += [f"{mod.path}.{identifier}", f"{mod.package.path}.{identifier}"]
        if context.is_class or context.parent is not None:
            parent = context if context.is_class else context.parent
            candidates.insert(1, f"{parent.path}.{identifier}")
    for c in candidates:
        try:
            obj = collection[c]
        except (KeyError, ValueError, Exception):  # noqa: BLE001 - unknown or unresolvable alias
            continue
        try:
            return obj.final_target.path if obj.is_alias else obj.path
        except Exception:  # noqa: BLE001
            return c
    return identifier


def convert(text: str, collection=None, context=None) -> str:
    """The docstring ``text`` with roles turned into optional cross-references and blank lines
    before lists and tables."""

    def role(m):
        tilde, target = m.group(1), m.group(2)
        title = target.rsplit(".", 1)[-1] if tilde else target
        ident = _resolve(collection, target, context) if collection is not None else target
        return f'<autoref identifier="{ident}" optional><code>{title}</code></autoref>'

    out, fence, prev = [], False, ""
    for line in text.splitlines():
        if line.lstrip().startswith("```"):
            fence = not fence
        if not fence:
            line = spec_links(ROLE.sub(role, line))
            if (BLOCK_START.match(line) and prev.strip() and not BLOCK_START.match(prev)
                    and not prev.startswith((" ", "\t")) and len(line) - len(line.lstrip()) == 0):
                out.append("")
        out.append(line)
        prev = line
    return "\n".join(out)


class JaxbeltDocstrings(griffe.Extension):
    """Rewrites every docstring of the loaded package (see the module docstring)."""

    def on_package(self, *, pkg, loader, **kwargs):
        collection = loader.modules_collection
        seen = set()

        def walk(obj):
            if obj.path in seen or obj.is_alias:
                return
            seen.add(obj.path)
            if obj.docstring is not None:
                obj.docstring.value = convert(obj.docstring.value, collection, obj)
            for member in obj.members.values():
                if not member.is_alias:
                    walk(member)

        walk(pkg)
