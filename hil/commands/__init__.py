"""One module per ``hil`` subcommand; :mod:`hil.cli` wires them to argparse."""
