"""Flags that several ``neurotrajectory`` subcommands share (beside :mod:`gridsim.cli.flags`):
one meaning and one wording per flag name."""

from __future__ import annotations

import argparse
import math

from gridsim.cli.flags import MAX_COUNT, at_least
from gridsim.seeding import MAX_SEED
from neurotrajectory.evolve.pareto import PICKS
from neurotrajectory.evolve.runs import RunError
from neurotrajectory.settings import Settings, base_type, bounds, choices, describe_number


def settings_flag(
    parser: argparse.ArgumentParser, settings: type[Settings], flag: str, **kwargs
) -> str:
    """Declare ``flag`` for the field of ``settings`` of its name (``--a-b``: ``a_b``; or
    ``dest``), its help the field's description (or ``help``) and its default. The flag's
    default is None (so that a command can tell a flag given from one not given; the
    field's default applies). An integer field parses as an integer within the field's
    bounds, a number as a finite float within them, a :class:`~neurotrajectory.settings.OneOf`
    field takes its choices; ``kwargs`` (``action``, ``nargs``, ...) go to argparse as given.
    Returns the field's name."""
    name = kwargs.pop("dest", flag.lstrip("-").replace("-", "_"))
    field = settings.model_fields[name]  # a KeyError here is a flag without its field: a bug
    kind = base_type(field)
    if "action" not in kwargs and "type" not in kwargs and "choices" not in kwargs:
        if kind is int:
            low = bounds(field).get("ge", 0)
            kwargs["type"] = at_least(low, MAX_SEED if name == "seed" else MAX_COUNT)
        elif kind is float:
            kwargs["type"] = number_in(bounds(field))
        if (options := choices(field)) is not None:
            kwargs["choices"] = options
    what = kwargs.pop("help", field.description)
    default = field.get_default(call_default_factory=True)
    if default is not None and not isinstance(default, bool | tuple | dict):
        shown = f"{default:g}" if isinstance(default, float) else (
            repr(default) if isinstance(default, str) else str(default))  # fmt: skip
        what += f" (default {shown})"
    parser.add_argument(flag, dest=name, default=None, help=what, **kwargs)
    return name


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


def number_in(limits: dict[str, float]):
    """An argparse type: a finite number within ``limits`` (some of ``gt``, ``ge``, ``lt``,
    ``le``, as :func:`~neurotrajectory.settings.bounds` gives them). argparse names the
    option in its error (``argument --sigma: expected a finite number in (0, 10], got
    'nan'``) and exits with status 2."""
    checks = {"gt": float.__gt__, "ge": float.__ge__, "lt": float.__lt__, "le": float.__le__}
    wanted = describe_number(float, limits)

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or not all(checks[k](value, float(v))
                                               for k, v in limits.items()):  # fmt: skip
            raise argparse.ArgumentTypeError(f"expected {wanted}, got {text!r}")
        return value

    parse.__name__ = wanted
    return parse


def episode_seconds(text: str) -> float:
    """An argparse type: an episode's length [s], within the bounds of a training run's
    ``episode_seconds``."""
    from neurotrajectory.evolve.runs import TrainConfig
    from neurotrajectory.settings import bounds

    return number_in(bounds(TrainConfig.model_fields["episode_seconds"]))(text)


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
