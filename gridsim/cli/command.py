"""Running a subcommand of ``gridsim`` or ``neurotrajectory``: parse, run, and turn its
errors into one line each (bad input: status 2; a bug: status 3, the traceback saved)."""

from __future__ import annotations

import argparse
import os
import select
import shlex
import sys
import tempfile
import traceback
import warnings
from functools import partial
from pathlib import Path

from gridsim import interrupts
from gridsim.errors import DataWarning, GridSimError
from gridsim.outputs import DISK_FULL

#: Where unexpected errors are to be reported.
REPORT_TO = "the GridSim issue tracker"


class HelpWithDefaults(argparse.HelpFormatter):
    """Help that states an option's default where its text does not already say it."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if (
            not action.option_strings
            or text == argparse.SUPPRESS
            or "default" in text
            or action.default is None
            or isinstance(action.default, bool)
            or action.default == argparse.SUPPRESS
        ):
            return action.help
        return f"{text} (default %(default)s)"


class Subcommand(argparse.ArgumentParser):
    """A subcommand's parser: its help states the defaults, and :func:`run_command` reports
    an unknown flag with this subcommand's usage (not the top-level one)."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("formatter_class", HelpWithDefaults)
        super().__init__(*args, **kwargs)
        self.set_defaults(_subcommand=self)


def add_subcommands(parser: argparse.ArgumentParser, modules) -> None:
    """The subcommands of ``parser``: each module's ``add_parser(sub)``, in order; and
    ``--version``."""
    from gridsim import __version__

    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Subcommand)
    for module in modules:
        module.add_parser(sub)


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
    with status 130 and no traceback; output piped to a reader that stops early (``| head``)
    ends it quietly with status 141."""
    args, unknown = parser.parse_known_args(argv)
    subcommand = vars(args).pop("_subcommand", parser)
    if unknown:  # with the usage of the subcommand they were given to
        subcommand.error(f"unrecognized arguments: {' '.join(unknown)}")
    #: the command line, as the user gave it (for files that record what made them)
    args.command = " ".join([parser.prog, *map(shlex.quote, sys.argv[1:] if argv is None
                                               else argv)])  # fmt: skip
    for flag in ("out", "run", "resume", "scenario"):
        if getattr(args, flag, None) == "":
            print(f"{parser.prog}: error: --{flag} is empty; give a path", file=sys.stderr)
            return 2
    with warnings.catch_warnings():
        warnings.simplefilter("default", DataWarning)
        warnings.showwarning = partial(_show_warning, parser.prog, set())
        try:
            with interrupts.deferred():  # Ctrl-C at the end of a simulator step
                return args.func(args)
        except errors as exc:
            print(f"{parser.prog}: error: {exc}", file=sys.stderr)
            return 2
        except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM
            said, status = interrupts.ended_by(exc)
            print(f"{parser.prog}: {said}", file=sys.stderr)
            return status
        except Exception as exc:
            if isinstance(exc, BrokenPipeError) and _stdout_closed():
                return 141  # the reader went away (`| head`): stop quietly, as a shell tool
            if isinstance(exc, OSError) and exc.errno in DISK_FULL:  # not a bug: the disk
                where = f"{exc.filename}: " if exc.filename else ""
                print(f"{parser.prog}: error: {where}{exc.strerror}; free some space (or write "
                      "elsewhere) and run it again", file=sys.stderr)  # fmt: skip
                return 2
            if os.environ.get("GRIDSIM_DEBUG"):
                raise
            saved = _save_traceback(parser.prog, args.command)
            print(f"{parser.prog}: internal error: {type(exc).__name__}: {exc}\n"
                  f"This is a bug, not a problem of your input. Please report it to {REPORT_TO} "
                  f"with the traceback saved in {saved}", file=sys.stderr)  # fmt: skip
            return 3


def _stdout_closed() -> bool:
    """Whether standard output's reader has gone (a flush fails, or the pipe reports an
    error: the failed write may have emptied the buffer); if so it is pointed at the null
    device, so that Python's own flush at exit does not fail on it again."""
    try:
        sys.stdout.flush()
        gone = _pipe_error(sys.stdout)
    except BrokenPipeError:
        gone = True
    if gone:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return gone


def _pipe_error(stream) -> bool:
    """Whether ``stream``'s file descriptor reports an error without blocking (the write end
    of a pipe whose reader has closed it)."""
    try:
        poll = select.poll()
        poll.register(stream.fileno(), select.POLLOUT)
        # (Linux reports a pipe whose reader has gone as POLLERR, macOS and BSD as POLLHUP)
        return any(events & (select.POLLERR | select.POLLHUP) for _, events in poll.poll(0))
    except (OSError, ValueError, AttributeError):  # not a pollable descriptor, no poll
        return False


def _show_warning(prog, shown: set, message, category, filename, lineno, file=None,
                  line=None) -> None:  # fmt: skip
    """A :class:`DataWarning` as ``PROG: warning: MESSAGE``, once per command (the same data
    is often loaded twice: to check it, then to use it); anything else as Python shows it."""
    from tqdm import tqdm  # (its write() puts the line above a progress bar, not on it)

    if issubclass(category, DataWarning):
        if str(message) not in shown:
            shown.add(str(message))
            tqdm.write(f"{prog}: warning: {message}", file=sys.stderr)
    else:
        tqdm.write(warnings.formatwarning(message, category, filename, lineno, line),
                   file=sys.stderr, end="")  # fmt: skip


def _save_traceback(prog: str, command: str) -> Path:
    """Write the current exception's traceback and the ``command`` line to a new file in the
    temporary folder; its path."""
    fd, name = tempfile.mkstemp(prefix=f"{prog}-crash-", suffix=".txt")
    with os.fdopen(fd, "w") as fh:
        fh.write(f"command: {command}\npython: {sys.version}\n\n{traceback.format_exc()}")
    return Path(name)
