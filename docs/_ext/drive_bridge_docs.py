"""Reference pages generated from the code, not written by hand.

``{drive-bridge-cli}``: every command with its whole ``--help`` (usage, every option, its
default), from the argparse parsers ``drive-bridge`` itself builds.  ``{drive-bridge-exit-codes}``:
the exit-code table of :mod:`drive_bridge.errors`, the one ``drive-bridge --help`` prints.
"""

from __future__ import annotations

import argparse
import os

from docutils import nodes
from docutils.parsers.rst import Directive

from drive_bridge.cli import build_parser
from drive_bridge.errors import EXIT_TABLE


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:  # argparse keeps them nowhere public
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


class CliReference(Directive):
    """Each command: a section with its description and its ``--help``."""

    def run(self):
        os.environ["COLUMNS"] = "100"  # the same width on every machine
        parser = build_parser()
        out = [nodes.literal_block(text=parser.format_help())]
        for name, sub in _subparsers(parser).items():
            section = nodes.section(ids=[f"command-{name}"], names=[f"drive-bridge {name}"])
            section += nodes.title(text=f"drive-bridge {name}")
            if sub.description:
                section += nodes.paragraph(text=sub.description)
            section += nodes.literal_block(text=sub.format_help())
            out.append(section)
        return out


class ExitCodes(Directive):
    """The exit-code table."""

    def run(self):
        table = nodes.table()
        group = nodes.tgroup(cols=3)
        table += group
        for width in (8, 20, 72):
            group += nodes.colspec(colwidth=width)
        head = nodes.thead()
        group += head
        body = nodes.tbody()
        group += body
        for target, cells in (
            (head, ("code", "kind", "meaning")),
            *((body, (str(code), kind, meaning)) for code, kind, meaning in EXIT_TABLE),
        ):
            row = nodes.row()
            for text in cells:
                entry = nodes.entry()
                entry += nodes.paragraph(text=text)
                row += entry
            target += row
        return [table]


def setup(app):
    app.add_directive("drive-bridge-cli", CliReference)
    app.add_directive("drive-bridge-exit-codes", ExitCodes)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
