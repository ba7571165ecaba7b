"""Ctrl-C at a chosen call: for tests of work that goes on after an interruption."""

from __future__ import annotations


def ctrl_c_at(monkeypatch, owner, name: str, call: int, after: bool = False) -> list:
    """Replace ``owner.name`` with one that raises KeyboardInterrupt at its ``call``-th call
    (from 1): before it runs, or ``after`` it ran. Returns the list of the calls' arguments
    (one tuple a call), which the test may clear to count again."""
    original, calls = getattr(owner, name), []

    def interrupted(*args, **kwargs):
        calls.append(args)
        if len(calls) == call and not after:
            raise KeyboardInterrupt
        result = original(*args, **kwargs)
        if len(calls) == call:
            raise KeyboardInterrupt
        return result

    monkeypatch.setattr(owner, name, interrupted)
    return calls
