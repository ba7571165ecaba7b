"""Flags that several subcommands of ``gridsim`` and ``neurotrajectory`` share: one meaning and
one wording per flag name, and the argparse types they parse with."""

from __future__ import annotations

import argparse

from gridsim.seeding import MAX_SEED

#: The largest count a flag takes (episodes, generations, steps, members): more would run
#: for days or fill the memory with per-episode results before anything is written.
MAX_COUNT = 100_000


def at_least(minimum: int, maximum: int = MAX_COUNT):
    """An argparse type: an integer in [``minimum``, ``maximum``]. argparse names the option
    in its error (``argument --seed: expected an integer >= 0, got -3``) and exits with
    status 2."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < minimum:
            raise argparse.ArgumentTypeError(f"expected an integer >= {minimum}, got {text!r}")
        if value > maximum:
            raise argparse.ArgumentTypeError(f"expected an integer <= {maximum:,}, got {text}")
        return value

    parse.__name__ = f"integer in [{minimum}, {maximum}]"
    return parse


def seed_flag(parser: argparse.ArgumentParser, what: str = "episode seed", **kwargs) -> None:
    """``--seed N``: an integer in [0, :data:`MAX_SEED`] (default 0; ``default=None`` where
    the command resolves it)."""
    kwargs.setdefault("default", 0)
    parser.add_argument("--seed", type=at_least(0, MAX_SEED), help=what, **kwargs)


def quiet_flag(parser: argparse.ArgumentParser, what: str = "no progress bar") -> None:
    """``--quiet``: no progress output."""
    parser.add_argument("--quiet", action="store_true", help=what)


def scenario_flag(parser: argparse.ArgumentParser, **kwargs) -> None:
    """``--scenario``: a built-in name, a YAML or CommonRoad XML path, a folder or glob of
    them, or a comma-separated list."""
    kwargs.setdefault("help", "built-in name, YAML/XML path, folder or glob")
    parser.add_argument("--scenario", **kwargs)


def overlay_flag(parser: argparse.ArgumentParser) -> None:
    """``--overlay`` / ``--no-overlay`` (default on): annotate the video (driver, time,
    speed, fitness so far, colour legend, scale bar)."""
    parser.add_argument("--overlay", action=argparse.BooleanOptionalAction, default=True,
                        help="annotate the video: who drives, time, speed, the fitness so far, "
                        "what the colours are and a scale bar (default on)")  # fmt: skip
