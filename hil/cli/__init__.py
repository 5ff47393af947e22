"""One module per ``hil`` subcommand; :mod:`hil.cli.main` wires them to argparse."""
