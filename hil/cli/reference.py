"""The command-line reference, generated from hil's own argparse parsers (``hil.cli.main.build_parser``): every
command, its usage, its options with their help, its examples.  The documentation site builds its "command line"
page from it (docs/_ext/hil_docs.py), and a test fails when an option or a command has no description — so the
page and ``--help`` say the same, and neither can leave an option unexplained."""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from dataclasses import dataclass

#: argparse keeps a parser's arguments and sub-commands under private names only (``_actions``,
#: ``_SubParsersAction`` …); these few lines are the one place hil reads them
Subparsers = argparse._SubParsersAction  # noqa: SLF001 - add_subparsers()'s type, public under no other name


def actions(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """The parser's arguments, in the order ``--help`` shows them."""
    return parser._actions  # noqa: SLF001 - argparse offers no public accessor


def options(parser: argparse.ArgumentParser) -> list[str]:
    """Every option string the parser takes: ``-h``, ``--help``, ``--bench`` …"""
    return [option for action in actions(parser) for option in action.option_strings]


@dataclass(frozen=True)
class Command:
    """One parser: ``hil``, ``hil run``, ``hil history trend`` …"""
    prog: str
    summary: str  # the help its parent lists it with
    parser: argparse.ArgumentParser


def commands(parser: argparse.ArgumentParser, summary: str = "") -> Iterator[Command]:
    """``parser`` and every sub-command under it, depth first, in the order ``--help`` lists them."""
    yield Command(parser.prog, summary, parser)
    for action in actions(parser):
        if isinstance(action, Subparsers):
            helps = {a.dest: a.help or "" for a in action._choices_actions}  # noqa: SLF001 - as actions()
            for name, sub in action.choices.items():
                if sub.prog.split()[-1] == name:  # (an alias points at the same parser: listed once)
                    yield from commands(sub, helps.get(name, ""))


def documented(action: argparse.Action) -> bool:
    """Shown in ``--help`` (an option whose help is SUPPRESS is hidden on purpose)."""
    return action.help is not argparse.SUPPRESS and not isinstance(action, Subparsers)


def undocumented(parser: argparse.ArgumentParser) -> list[str]:
    """Every command without a description and every shown option without help, as ``prog: option``."""
    missing = []
    for command in commands(parser):
        if not (command.parser.description or command.summary):
            missing.append(f"{command.prog}: (the command itself)")
        for action in actions(command.parser):
            if documented(action) and not (action.help or "").strip():
                missing.append(f"{command.prog}: {', '.join(action.option_strings) or action.dest}")
    return missing


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def _option(action: argparse.Action) -> str:
    names = ", ".join(f"`{o}`" for o in action.option_strings) or f"`{action.metavar or action.dest}`"
    if action.option_strings and action.nargs != 0:
        names += f" `{action.metavar or action.dest.upper()}`"
    return names


def _help(action: argparse.Action) -> str:
    """The option's help as ``--help`` prints it (``%(default)s`` filled in)."""
    text = action.help or ""
    return text % vars(action) if "%(" in text else text


def render(parser: argparse.ArgumentParser) -> str:
    """The reference as Markdown (MyST): a section per command."""
    out = ["# Every command and option", "",
           "Generated from hil's argparse parsers when this site was built: the same text as `--help`.", ""]
    for command in commands(parser):
        depth = min(command.prog.count(" ") + 1, 4)
        out += [f"{'#' * (depth + 1)} `{command.prog}`", ""]
        text = command.parser.description or command.summary
        if text:
            out += [" ".join(text.split()), ""]
        usage = command.parser.format_usage().removeprefix("usage: ").strip()
        out += ["```text", usage, "```", ""]
        rows = [f"| {_option(a)} | {_cell(_help(a))} |" for a in actions(command.parser)
                if documented(a) and "--help" not in a.option_strings]
        if rows:
            out += ["| option | what it does |", "|---|---|", *rows, ""]
        if command.parser.epilog:
            out += ["```text", command.parser.epilog.strip("\n"), "```", ""]
    return "\n".join(out)
