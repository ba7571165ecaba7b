"""Ctrl-C (and SIGTERM) deferred to the end of the simulator step it arrives in, for commands.

Python raises ``KeyboardInterrupt`` between bytecodes; arriving while a compiled (numba)
call returns, it can leave the interpreter in a bad state: the command ends in a
segmentation fault or a ``SystemError`` instead of its "interrupted" message (seen when
interrupting ``record`` and ``train --backend local``). Commands install
:func:`deferred` around their work; every :meth:`GridSimEnv.step
<gridsim.envs.gridsim_env.GridSimEnv.step>` and ``reset`` is a critical section
(:func:`enter` ... :func:`leave`), at whose end a Ctrl-C that arrived inside it is raised.
Outside such sections, and in programs that do not install it, Ctrl-C is Python's own.
SIGTERM (``kill``, a job scheduler's stop, a container's) is handled alike, as
:class:`Terminated`: the command ends as after Ctrl-C, saying what it kept (the default
action ended the process without a word).
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_STATE: dict = {"depth": 0, "pending": None}  # pending: the interrupt to raise at leave()


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where Ctrl-C's ``KeyboardInterrupt`` would be (a kind of it: work
    that handles Ctrl-C handles it too)."""


def ended_by(exc: KeyboardInterrupt) -> tuple[str, int]:
    """What a command says ended it, and its exit status: ``("interrupted", 130)`` for
    Ctrl-C, ``("terminated (SIGTERM)", 143)`` for :class:`Terminated` (128 + the signal)."""
    if isinstance(exc, Terminated):
        return "terminated (SIGTERM)", 143
    return "interrupted", 130


def enter() -> None:
    """Begin a critical section (nested sections are one)."""
    _STATE["depth"] += 1


def leave() -> None:
    """End a critical section; a Ctrl-C that arrived inside it is raised now."""
    _STATE["depth"] -= 1
    if not _STATE["depth"] and _STATE["pending"] is not None:
        pending, _STATE["pending"] = _STATE["pending"], None
        raise pending()


def _handler(signum, frame) -> None:
    interrupt = Terminated if signum == signal.SIGTERM else KeyboardInterrupt
    if _STATE["depth"]:
        _STATE["pending"] = _STATE["pending"] or interrupt  # raised by leave()
    else:
        raise interrupt()


@contextmanager
def deferred() -> Iterator[None]:
    """Within it, a Ctrl-C inside a critical section waits for the section's end (in the main
    thread, if Ctrl-C is Python's default there), and so does a SIGTERM, raised as
    :class:`Terminated` (if its handling is the default: also where Ctrl-C is ignored, as
    in a shell's background job); else nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    ctrl_c = signal.getsignal(signal.SIGINT) is signal.default_int_handler
    term = signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    previous = signal.signal(signal.SIGINT, _handler) if ctrl_c else None
    if term:
        signal.signal(signal.SIGTERM, _handler)
    try:
        yield
    finally:
        if ctrl_c:
            signal.signal(signal.SIGINT, previous)
        if term:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
        _STATE["pending"] = None
