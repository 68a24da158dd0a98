"""Every ``preisach ... --help`` text reads as printed: no literal ``%%`` or ``%(`` left."""

from __future__ import annotations

import argparse

from preisach.cli import _build_parser


def _parsers(parser: argparse.ArgumentParser, prog: str = "preisach"):
    yield prog, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, f"{prog} {name}")


def test_no_help_text_shows_format_escapes():
    seen = []
    for prog, parser in _parsers(_build_parser()):
        text = parser.format_help()
        assert "%%" not in text and "%(" not in text, f"{prog} --help:\n{text}"
        seen.append(prog)
    assert {"preisach identify", "preisach verify", "preisach demo"} <= set(seen)
