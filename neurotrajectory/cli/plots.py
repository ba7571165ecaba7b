"""``neurotrajectory plots``: draw a run's plots again (as this version draws them)."""

from __future__ import annotations

import argparse

from neurotrajectory.cli.flags import run_flag


def add_parser(sub) -> None:
    p = sub.add_parser("plots", help="draw a run's plots again, from its saved scores")
    run_flag(p)
    p.set_defaults(func=execute)


def execute(args: argparse.Namespace) -> int:
    from neurotrajectory.evolve.runs import Run

    # (no lock: it reads the run's saved scores and only writes plots/)
    print("\n".join(str(p) for p in Run.open(args.run).plot()))
    return 0
