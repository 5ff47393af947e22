"""The command table (issue 41): each ``hil`` command lives in its own module, which adds its parser and binds its
function; the table names the module, and only the chosen command's module is imported."""

from __future__ import annotations

import subprocess
import sys

from hil.cli.main import COMMANDS, build_parser
from hil.cli.reference import Subparsers, actions, commands


def test_each_command_of_the_table_is_its_modules_parser() -> None:
    parser = build_parser()
    listed = next(a for a in actions(parser) if isinstance(a, Subparsers))
    assert list(listed.choices) == list(COMMANDS)  # in the table's order, as hil --help lists them
    for name, parsed in listed.choices.items():
        assert parsed.prog == f"hil {name}"


def test_every_command_a_user_can_type_has_a_function() -> None:
    """A leaf of the tree (``hil probe``, ``hil rtc read``, ``hil history trend``) is bound to what runs it, by
    itself or by the command it belongs to (``hil history`` runs each of its actions)."""
    found = {command.prog: command.parser for command in commands(build_parser())}
    for prog, parser in found.items():
        if prog != "hil" and not any(isinstance(a, Subparsers) for a in actions(parser)):
            words = prog.split()
            bound = [found[" ".join(words[:n])].get_default("func") for n in range(2, len(words) + 1)]
            assert any(callable(func) for func in bound), prog


def test_only_the_chosen_commands_module_is_imported() -> None:
    """``hil drift code`` imports hil.cli.drift, not pytest's runner, the emulator or the history's SQLAlchemy."""
    shown = subprocess.run([sys.executable, "-c", "import sys\nfrom hil.cli.main import main\nmain(['drift', 'code', "
                            "'1'])\nprint(sorted(m for m in sys.modules if m.startswith('hil.cli.')))"],
                           capture_output=True, text=True, timeout=120, check=True).stdout.splitlines()[-1]
    assert "'hil.cli.drift'" in shown
    for other in ("run", "history", "emulate", "spec", "init"):
        assert f"'hil.cli.{other}'" not in shown, shown
