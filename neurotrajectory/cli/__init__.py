"""The ``neurotrajectory`` command line: one module per subcommand (``train``, ``rollout``,
``heldout``, ``record``, ``evaluate``, ``plots``), each with ``add_parser(sub)`` and
``execute(args)``; the flags they share in :mod:`~neurotrajectory.cli.flags` and
:mod:`gridsim.cli.flags`."""

from __future__ import annotations

import argparse
import sys

from gridsim.cli.command import add_subcommands, run_command
from gridsim.errors import GridSimError
from neurotrajectory.cli import evaluate, heldout, plots, record, rollout, train
from neurotrajectory.evolve.backends import BackendError
from neurotrajectory.evolve.runs import RunError

#: The subcommands, in the order ``neurotrajectory --help`` lists them.
SUBCOMMANDS = (train, rollout, heldout, record, evaluate, plots)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="neurotrajectory", description="NeuroTrajectory: neuroevolution of local trajectories."
    )
    add_subcommands(p, SUBCOMMANDS)
    return p


def main(argv: list[str] | None = None) -> int:
    return run_command(build_parser(), argv, (GridSimError, RunError, BackendError, ValueError))


if __name__ == "__main__":
    sys.exit(main())
