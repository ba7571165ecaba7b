"""The ``gridsim`` command line."""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import tempfile
import traceback
import warnings
from functools import partial
from pathlib import Path

from gridsim.errors import DataWarning, GridSimError

POLICY_NAMES = ("idle", "reference", "lane-follow", "random")


#: The largest count a flag takes (episodes, generations, steps, members): more would run
#: for days or fill the memory with per-episode results before anything is written.
MAX_COUNT = 100_000
#: The largest seed a flag takes.
MAX_SEED = 2**32 - 1


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


def _cmd_scenarios(args: argparse.Namespace) -> int:
    from gridsim.scenario.collection import load_collection
    from gridsim.scenario.loader import builtin_scenarios

    if args.path is None:
        for name, desc in builtin_scenarios().items():
            print(f"{name:16s} {desc}")
        return 0
    for sc in load_collection(args.path):
        print(f"{sc.source}: {sc.name} ({sc.config.road.type}) {sc.config.description}")
    return 0


def _report(path: str):
    """``(summary, report)`` of one scenario file: it loads, builds, and its recorded data
    (if any) is plausible (:class:`~gridsim.scenario.checks.SceneReport`)."""
    from gridsim.scenario.build import build_world
    from gridsim.scenario.checks import scenario_report
    from gridsim.scenario.loader import load_scenario

    sc = load_scenario(path)
    report = scenario_report(sc)
    if not report.problems:
        with warnings.catch_warnings():  # the report lists them
            warnings.simplefilter("ignore", DataWarning)
            build_world(sc, seed=0)  # also resolves maps and libraries
    return f"scenario {sc.name!r}, road type {sc.config.road.type}", report


def _cmd_validate(args: argparse.Namespace) -> int:
    from gridsim.errors import DataError
    from gridsim.scenario.collection import scenario_files

    files = scenario_files(args.path)
    if files is None:  # one file: its problems are the error
        summary, report = _report(args.path)
        if report.problems:
            raise DataError(report.refusal(args.path))
        print(f"{args.path}: OK ({summary})" + _warning_lines(report.warnings))
        return 0
    failed = 0
    for f in files:  # a collection: one line per file, its problems below it
        try:
            summary, report = _report(str(f))
            problems, notes = report.problems, report.warnings
        except GridSimError as exc:
            summary, problems, notes = "error", str(exc).splitlines(), ()
        if problems:
            failed += 1
            print(f"{f}: {len(problems)} problem(s)")
            print("\n".join(f"  - {p.strip().removeprefix('- ')}" for p in problems))
        else:
            print(f"{f}: OK ({summary})" + _warning_lines(notes))
    print(f"{len(files) - failed} of {len(files)} scenario files OK")
    return 2 if failed else 0


def _warning_lines(notes: tuple[str, ...]) -> str:
    return "".join(f"\n  warning: {n}" for n in notes)


def _cmd_import(args: argparse.Namespace) -> int:
    from gridsim.scenario.collection import scenario_files
    from gridsim.scenario.importer import import_files

    files = []
    for src in args.sources:
        found = scenario_files(src)
        files += [Path(src)] if found is None else [f for f in found if f.suffix == ".xml"]
    for path in import_files(files, args.out):
        print(f"wrote {path}")
    return 0


def _cmd_drive(args: argparse.Namespace) -> int:
    from gridsim.cli.drive import drive

    summary = drive(args.scenario, args.seconds, args.seed, Path(args.out), progress=not args.quiet)
    print(json.dumps(summary, indent=2))
    return 0


def _cmd_compile(args: argparse.Namespace) -> int:
    from gridsim.cli.compile import compile_kernels

    print("compiling or loading the kernels of every built-in scenario:")
    done = compile_kernels()
    print(f"{done['kernels']} kernels ready ({done['compiled']} compilations) in "
          f"{done['seconds']:g} s")  # fmt: skip
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    from gridsim.cli.run import run_policy

    summary = run_policy(
        args.scenario, args.policy, args.steps, args.seed, video=args.video,
        progress=not args.quiet, overlay=args.overlay,
    )  # fmt: skip
    print(json.dumps(summary, indent=2))
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="gridsim", description="Headless GridSim driving simulator.")
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser(
        "scenarios", help="list the built-in scenarios, or the scenarios of a folder or glob"
    )
    s.add_argument("path", nargs="?", default=None, help="a folder or glob of scenario files")
    s.set_defaults(func=_cmd_scenarios)
    s = sub.add_parser(
        "validate",
        help="check a scenario file (YAML or CommonRoad XML; and a recorded scene's data), or "
        "each file of a folder or glob, and print precise errors",
    )
    s.add_argument("path")
    s.set_defaults(func=_cmd_validate)
    s = sub.add_parser(
        "import",
        help="write scenario YAML and trajectory CSV files from CommonRoad files, to edit",
    )
    s.add_argument("sources", nargs="+", help="CommonRoad .xml files, folders or globs")
    s.add_argument("--out", required=True, help="output folder (YAML, CSV and maps/)")
    s.set_defaults(func=_cmd_import)
    s = sub.add_parser("run", help="drive a policy in GridSim-v0, print a summary, export a video")
    s.add_argument(
        "--scenario", default="seamless", help="built-in name, YAML/XML path, folder or glob"
    )
    s.add_argument("--steps", type=at_least(1), default=300, help="decisions to run at most")
    s.add_argument(
        "--policy",
        default="reference",
        choices=POLICY_NAMES,
        help="the driver: the human reference, lane following, random or idle",
    )
    s.add_argument("--seed", type=at_least(0, MAX_SEED), default=0, help="episode seed")
    s.add_argument("--video", default=None, help="write a video (.mp4, or .gif)")
    overlay_flag(s)
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=_cmd_run)
    s = sub.add_parser(
        "drive", help="drive the lane-following ego; write grids and a top-down frame"
    )
    s.add_argument(
        "--scenario", default="seamless", help="built-in name, YAML/XML path, folder or glob"
    )
    s.add_argument("--seconds", type=float, default=20.0, help="simulated time [s]")
    s.add_argument("--seed", type=at_least(0, MAX_SEED), default=0, help="episode seed")
    s.add_argument("--out", default="out/drive", help="output folder")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=_cmd_drive)
    s = sub.add_parser(
        "compile",
        help="compile the simulator's kernels for this machine and cache them (pip install . "
        "does it; run it after an editable install, or to fill a read-only install's cache)",
    )
    s.set_defaults(func=_cmd_compile)
    return p


def overlay_flag(parser: argparse.ArgumentParser) -> None:
    """``--overlay`` / ``--no-overlay`` (default on): annotate the video (driver, time,
    speed, fitness so far, colour legend, scale bar)."""
    parser.add_argument("--overlay", action=argparse.BooleanOptionalAction, default=True,
                        help="annotate the video: who drives, time, speed, the fitness so far, "
                        "what the colours are and a scale bar (default on)")  # fmt: skip


#: Where unexpected errors are to be reported.
REPORT_TO = "the GridSim issue tracker"


def run_command(
    parser: argparse.ArgumentParser,
    argv: list[str] | None,
    errors: tuple[type[Exception], ...] = (GridSimError,),
) -> int:
    """Parse ``argv`` and run the chosen sub-command's ``func``. An expected error (one of
    ``errors``: bad input, named by the message) is printed as ``PROG: error: MESSAGE`` with
    exit status 2, as argparse prints a bad flag; a :class:`~gridsim.errors.DataWarning` as
    ``PROG: warning: MESSAGE``. Anything else is a bug: one line says so and where the
    traceback was saved (exit status 3; ``GRIDSIM_DEBUG=1`` raises it instead); Ctrl-C exits
    with status 130 and no traceback."""
    args = parser.parse_args(argv)
    #: the command line, as the user gave it (for files that record what made them)
    args.command = " ".join([parser.prog, *map(shlex.quote, sys.argv[1:] if argv is None
                                               else argv)])  # fmt: skip
    for flag in ("out", "run", "resume", "scenario"):
        if getattr(args, flag, None) == "":
            print(f"{parser.prog}: error: --{flag} is empty; give a path", file=sys.stderr)
            return 2
    with warnings.catch_warnings():
        warnings.simplefilter("default", DataWarning)
        warnings.showwarning = partial(_show_warning, parser.prog)
        try:
            return args.func(args)
        except errors as exc:
            print(f"{parser.prog}: error: {exc}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print(f"{parser.prog}: interrupted", file=sys.stderr)
            return 130
        except Exception as exc:
            if os.environ.get("GRIDSIM_DEBUG"):
                raise
            saved = _save_traceback(parser.prog, args.command)
            print(f"{parser.prog}: internal error: {type(exc).__name__}: {exc}\n"
                  f"This is a bug, not a problem of your input. Please report it to {REPORT_TO} "
                  f"with the traceback saved in {saved}", file=sys.stderr)  # fmt: skip
            return 3


def _show_warning(prog, message, category, filename, lineno, file=None, line=None) -> None:
    if issubclass(category, DataWarning):
        print(f"{prog}: warning: {message}", file=sys.stderr)
    else:
        print(warnings.formatwarning(message, category, filename, lineno, line), file=sys.stderr,
              end="")  # fmt: skip


def _save_traceback(prog: str, command: str) -> Path:
    """Write the current exception's traceback and the ``command`` line to a new file in the
    temporary folder; its path."""
    fd, name = tempfile.mkstemp(prefix=f"{prog}-crash-", suffix=".txt")
    with os.fdopen(fd, "w") as fh:
        fh.write(f"command: {command}\npython: {sys.version}\n\n{traceback.format_exc()}")
    return Path(name)


def main(argv: list[str] | None = None) -> int:
    return run_command(build_parser(), argv)


if __name__ == "__main__":
    sys.exit(main())
