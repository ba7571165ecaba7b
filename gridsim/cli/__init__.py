"""The ``gridsim`` command line: one module per subcommand, each with ``add_parser(sub)``
(its flags, from :mod:`~gridsim.cli.flags` where shared) and ``execute(args)``; the modules
import what they run only when they run it, so that ``gridsim --help`` answers at once."""

from __future__ import annotations

import argparse
import sys

from gridsim.cli import compile, drive, import_, run, scenarios, validate
from gridsim.cli.command import add_subcommands, run_command

#: The subcommands, in the order ``gridsim --help`` lists them.
SUBCOMMANDS = (scenarios, validate, import_, run, drive, compile)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="gridsim", description="Headless GridSim driving simulator.")
    add_subcommands(p, SUBCOMMANDS)
    return p


def main(argv: list[str] | None = None) -> int:
    return run_command(build_parser(), argv)


if __name__ == "__main__":
    sys.exit(main())
