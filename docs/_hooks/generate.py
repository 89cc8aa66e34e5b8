"""MkDocs hook: pages generated from the code at build time.

Two placeholders, each on a line of its own in a Markdown page, are replaced
before the page is rendered:

* ``<!-- gd:cli-reference -->``: every command of ``gyrodenoise`` with its
  usage and options, walked from :func:`gyrodenoise.cli.build_parser` (the
  parser the program runs, so the page cannot disagree with ``--help``);
* ``<!-- gd:fmu-variables -->``: the variable tables of every FMU, from
  :func:`gyrodenoise.fmu.variables.markdown_tables` (the one declaration both
  FMU kinds are built from).

Registered in ``mkdocs.yml`` under ``hooks:``.
"""

from __future__ import annotations

import argparse
import contextlib
import os

CLI_PLACEHOLDER = "<!-- gd:cli-reference -->"
FMU_PLACEHOLDER = "<!-- gd:fmu-variables -->"
FMU3_PLACEHOLDER = "<!-- gd:fmu3-variables -->"

#: help text is wrapped at this many columns, whatever the terminal building the site
HELP_WIDTH_COLUMNS = 100


@contextlib.contextmanager
def _columns(width):
    """argparse wraps help at $COLUMNS: fix it while the help is formatted."""
    before = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(width)
    try:
        yield
    finally:
        if before is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = before


def _subcommands(parser):
    """(name, parser, one-line help) of each subcommand of ``parser``, in declaration order."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help for a in action._choices_actions}
            for name, sub in action.choices.items():
                yield name, sub, helps.get(name) or ""


def _walk(parser, depth=0):
    """Every (sub)command below ``parser``, depth first: (parser, help, depth)."""
    for _name, sub, summary in _subcommands(parser):
        yield sub, summary, depth
        yield from _walk(sub, depth + 1)


def cli_reference_markdown():
    """Markdown for every ``gyrodenoise`` command: a heading, its one-line summary
    and its ``--help`` text, in the order the parser declares them."""
    from gyrodenoise.cli import build_parser

    parser = build_parser()
    lines = []
    with _columns(HELP_WIDTH_COLUMNS):
        lines += ["## `gyrodenoise`", "", "```text", parser.format_help().rstrip(), "```", ""]
        for sub, summary, depth in _walk(parser):
            lines += ["#" * (depth + 2) + f" `{sub.prog}`", ""]
            if summary:
                lines += [summary[0].upper() + summary[1:] + ".", ""]
            lines += ["```text", sub.format_help().rstrip(), "```", ""]
    return "\n".join(lines)


def fmu_variables_markdown():
    """The FMU variable tables, from the one declaration of the FMUs' variables."""
    from gyrodenoise.fmu.variables import markdown_tables

    return markdown_tables()


def fmu3_variables_markdown():
    """The FMI 3.0 FMUs' variable tables (FMI 3.0 types), from the same declaration."""
    from gyrodenoise.fmu.variables import markdown_tables

    return markdown_tables(fmi_version=3)


_GENERATORS = {CLI_PLACEHOLDER: cli_reference_markdown, FMU_PLACEHOLDER: fmu_variables_markdown,
               FMU3_PLACEHOLDER: fmu3_variables_markdown}


def on_page_markdown(markdown, page, config, files):
    """Replace each placeholder line of a page by the text generated for it."""
    for placeholder, generate in _GENERATORS.items():
        if placeholder in markdown:
            markdown = markdown.replace(placeholder, generate())
    return markdown
