"""Ctrl-C deferred to the end of the simulator step it arrives in, for commands.

Python raises ``KeyboardInterrupt`` between bytecodes; arriving while a compiled (numba)
call returns, it can leave the interpreter in a bad state: the command ends in a
segmentation fault or a ``SystemError`` instead of its "interrupted" message (seen when
interrupting ``record`` and ``train --backend local``). Commands install
:func:`deferred` around their work; every :meth:`GridSimEnv.step
<gridsim.envs.gridsim_env.GridSimEnv.step>` and ``reset`` is a critical section
(:func:`enter` ... :func:`leave`), at whose end a Ctrl-C that arrived inside it is raised.
Outside such sections, and in programs that do not install it, Ctrl-C is Python's own.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_STATE = {"depth": 0, "pending": False}


def enter() -> None:
    """Begin a critical section (nested sections are one)."""
    _STATE["depth"] += 1


def leave() -> None:
    """End a critical section; a Ctrl-C that arrived inside it is raised now."""
    _STATE["depth"] -= 1
    if not _STATE["depth"] and _STATE["pending"]:
        _STATE["pending"] = False
        raise KeyboardInterrupt


def _handler(signum, frame) -> None:
    if _STATE["depth"]:
        _STATE["pending"] = True  # raised by leave()
    else:
        raise KeyboardInterrupt


@contextmanager
def deferred() -> Iterator[None]:
    """Within it, a Ctrl-C inside a critical section waits for the section's end (in the main
    thread, if Ctrl-C is Python's default there; else nothing changes)."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):  # fmt: skip
        yield
        return
    previous = signal.signal(signal.SIGINT, _handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        _STATE["pending"] = False
