"""A run of one command builds only that command's parser (imunoise.cli.build_parser(command)): the same
options, help and choices as in the full parser, and a word that names no command falls back to it."""

from __future__ import annotations

import argparse

import pytest

from imunoise.cli import build_parser


def _commands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


FULL = _commands(build_parser())


@pytest.mark.parametrize("command", sorted(FULL))
def test_one_command_parser_is_the_full_parsers_subparser(command):
    one = build_parser(command)
    assert one is not None and sorted(_commands(one)) == [command]
    sub, full = _commands(one)[command], FULL[command]
    assert sub.format_help() == full.format_help()
    assert [_spec(a) for a in sub._actions] == [_spec(a) for a in full._actions]


def _spec(a: argparse.Action) -> tuple:
    kind = getattr(a.type, "__qualname__", a.type)  # a validator made per registration: compare its kind
    return a.option_strings, a.dest, a.default, kind, a.choices, a.nargs, a.required


@pytest.mark.parametrize("word", ["navv", "options", "kernel_cache", "_version"])
def test_a_word_that_names_no_command_gets_no_parser(word):
    assert build_parser(word) is None
