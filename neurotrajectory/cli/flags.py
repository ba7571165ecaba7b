"""Flags that several ``neurotrajectory`` subcommands share (beside :mod:`gridsim.cli.flags`):
one meaning and one wording per flag name."""

from __future__ import annotations

import argparse
import math

from neurotrajectory.evolve.pareto import PICKS
from neurotrajectory.evolve.runs import RunError


def run_flag(parser: argparse.ArgumentParser, what: str = "a finished training run's folder"):
    """``--run DIR``: a training run's folder (required)."""
    parser.add_argument("--run", required=True, help=what)


def pick_flag(
    parser: argparse.ArgumentParser,
    what: str = "the front member: the knee or the best on one objective",
) -> None:
    """``--pick``: which member of a run's front (default the knee)."""
    parser.add_argument("--pick", default="knee", choices=PICKS, help=what)


def goal_flag(parser: argparse.ArgumentParser, who: str) -> None:
    """``--goal-seconds S``: the scenario's ``env.goal_seconds`` (None: at the last
    set-point)."""
    parser.add_argument(
        "--goal-seconds",
        dest="goal_seconds",
        type=positive_seconds,
        default=None,
        metavar="S",
        help=f"{who} S seconds ahead, beyond the last set-point (>= the horizon's 2.5 s; "
        "default: at the last set-point, where the human will be)",
    )


def plan_smoothing_flag(parser: argparse.ArgumentParser, what: str) -> None:
    """``--plan-smoothing KEEP``: the share of the previous plan kept in each new one."""
    parser.add_argument("--plan-smoothing", dest="plan_smoothing", type=float, default=None,
                        metavar="KEEP", help=what)  # fmt: skip


def episode_seconds_flag(parser: argparse.ArgumentParser, what: str, **kwargs) -> None:
    """``--episode-seconds S``: the length of each episode [s]."""
    kwargs.setdefault("default", None)
    parser.add_argument("--episode-seconds", dest="episode_seconds", type=float, help=what,
                        **kwargs)  # fmt: skip


def test_fraction_flag(parser: argparse.ArgumentParser, what: str, **kwargs) -> None:
    """``--test-fraction F``: the share of the tracks on the test side of the split."""
    kwargs.setdefault("default", None)
    parser.add_argument("--test-fraction", dest="test_fraction", type=float, help=what, **kwargs)


def positive_seconds(text: str) -> float:
    """An argparse type: a finite number of seconds > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number of seconds > 0, got {text}")
    return value


def check_video(path: str) -> None:
    """Refuse a video path that cannot be written (before any work is done)."""
    from gridsim.video import video_problem

    problem = video_problem(path)
    if problem:
        raise RunError(f"--video {path}: {problem}")
