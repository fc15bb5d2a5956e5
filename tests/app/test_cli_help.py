"""The help texts read as they are meant: argparse formats ``%`` only in argument help, so a
description must not escape it."""

import pytest

from cdus.app.cli import build_parser


def subparsers():
    parser = build_parser()
    (action,) = [a for a in parser._subparsers._group_actions]
    return action.choices


@pytest.mark.parametrize("name", sorted(subparsers()))
def test_no_escaped_percent_in_a_subcommand_help(name):
    text = subparsers()[name].format_help()
    assert "%%" not in text
