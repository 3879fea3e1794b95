"""The command-line reference of ``jaxbelt``, generated from its argparse parsers.

``python scripts/cli_reference.py`` prints it as Markdown; the docs build calls :func:`markdown`
(``scripts/mkdocs_hooks.py``) to fill ``docs/cli.md``, so the page lists every command and option
that :func:`jaxbelt.cli.build_parser` defines and cannot go stale.
"""

from __future__ import annotations

import argparse


def _cell(text) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _usage(parser: argparse.ArgumentParser) -> str:
    return " ".join(parser.format_usage().removeprefix("usage: ").split())


def _option_rows(parser: argparse.ArgumentParser):
    rows = []
    for a in parser._actions:
        if isinstance(a, (argparse._HelpAction, argparse._SubParsersAction)):
            continue
        if a.option_strings:
            name = ", ".join(f"`{o}`" for o in a.option_strings)
            if a.nargs == 0:
                value = ""
            elif a.choices:
                value = " \\| ".join(f"`{c}`" for c in a.choices)
            else:
                value = f"`{a.metavar or a.dest.upper()}`" + (f" ({a.type.__name__})" if a.type not in (None, str) else "")
            if a.nargs in ("+", "*"):
                value += " …"
        else:
            name = f"`{a.metavar or a.dest}`" + (" (optional)" if a.nargs == "?" else "")
            value = " \\| ".join(f"`{c}`" for c in a.choices) if a.choices else ""
            if a.nargs in ("+", "*"):
                value += " …"
        if a.required and a.option_strings:
            name += " (required)"
        default = "" if a.default in (None, False, argparse.SUPPRESS) or a.nargs == 0 else f"`{a.default}`"
        rows.append((name, value, default, (a.help or "").replace("%%", "%")))
    return rows


def markdown(heading_level: int = 2) -> str:
    """Markdown for every command of :func:`jaxbelt.cli.build_parser`: usage, its help line and a
    table of its arguments (name, value, default, help), in the order of ``jaxbelt --help``."""
    from jaxbelt.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    helps = {c.dest: c.help for c in sub._choices_actions}
    h = "#" * heading_level
    out = [f"```text\n{_usage(parser)}\n```\n", f"{parser.description}.\n"]
    out.append("| command | what it does |\n|---|---|")
    out += [f"| [`jaxbelt {name}`](#jaxbelt-{name}) | {_cell(helps.get(name, ''))} |" for name in sub.choices]
    out.append("")
    for name, p in sub.choices.items():
        out.append(f"{h} `jaxbelt {name}` {{#jaxbelt-{name}}}\n")
        out.append(f"{helps.get(name, '')}\n" if helps.get(name) else "")
        out.append(f"```text\n{_usage(p)}\n```\n")
        rows = _option_rows(p)
        if rows:
            out.append("| argument | value | default | description |\n|---|---|---|---|")
            out += [f"| {_cell(n)} | {_cell(v)} | {_cell(d)} | {_cell(hp)} |" for n, v, d, hp in rows]
            out.append("")
    return "\n".join(out)


if __name__ == "__main__":
    print(markdown())
