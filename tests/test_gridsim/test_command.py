"""How a command ends: a reader that stops early (``| head``) is not a bug."""

import argparse
import io
import os
import sys

import pytest

from gridsim.cli.command import run_command


class ClosedPipe(io.StringIO):
    """Standard output whose reader has gone."""

    def flush(self):
        raise BrokenPipeError(32, "Broken pipe")

    def fileno(self):
        return self._fd


def _parser(func) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="gridsim")
    p.set_defaults(func=func)
    return p


def _broken(args):
    raise BrokenPipeError(32, "Broken pipe")


def test_a_reader_that_stops_early_ends_the_command_quietly(monkeypatch, tmp_path, capsys):
    stdout = ClosedPipe()
    stdout._fd = os.open(tmp_path / "out", os.O_WRONLY | os.O_CREAT)  # pointed at /dev/null
    monkeypatch.setattr(sys, "stdout", stdout)
    try:
        assert run_command(_parser(_broken), []) == 141
    finally:
        os.close(stdout._fd)
    assert capsys.readouterr().err == ""


def test_a_broken_pipe_elsewhere_is_still_reported(capsys):
    """(a worker's pipe, say, while standard output is fine)"""
    assert run_command(_parser(_broken), []) == 3
    assert "internal error: BrokenPipeError" in capsys.readouterr().err


def test_a_real_pipe_closed_before_the_output_ends_the_command_quietly():
    """The failed write empties Python's buffer, so a flush afterwards succeeds: the closed
    pipe is seen by polling it (`gridsim validate --resolved X | head -1` said "internal
    error")."""
    import subprocess

    read, write = os.pipe()
    os.close(read)  # the reader has gone before the command writes anything
    try:
        done = subprocess.run([sys.executable, "-m", "gridsim", "validate", "--resolved",
                               "inner_city"], stdout=write, stderr=subprocess.PIPE, text=True,
                              timeout=120)  # fmt: skip
    finally:
        os.close(write)
    assert done.returncode == 141, done.stderr
    assert "internal error" not in done.stderr


def test_a_ctrl_c_inside_a_simulator_step_waits_for_its_end():
    """Python raises Ctrl-C between bytecodes, also as a compiled call returns, which could
    crash the interpreter (interrupted record and train --backend local ended in segfaults):
    in commands it is raised at the end of the step it arrives in."""
    import signal

    import gymnasium as gym
    import pytest

    from gridsim import interrupts

    env = gym.make("GridSim-v0", simulation={"duration": 5.0})
    _, info = env.reset(seed=0)
    reached = []
    inner = env.unwrapped._step

    def step_that_is_interrupted(action):
        os.kill(os.getpid(), signal.SIGINT)  # arrives in the middle of the step
        result = inner(action)
        reached.append("the step's end")
        return result

    env.unwrapped._step = step_that_is_interrupted
    with interrupts.deferred(), pytest.raises(KeyboardInterrupt):
        env.step(info["reference_setpoints"])
    assert reached == ["the step's end"]
    with interrupts.deferred(), pytest.raises(KeyboardInterrupt):  # outside a step: at once
        os.kill(os.getpid(), signal.SIGINT)
        reached.append("after the signal")
    assert reached == ["the step's end"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # put back
    with pytest.raises(KeyboardInterrupt):  # a library user's program: Python's own
        env.step(info["reference_setpoints"])
    assert reached == ["the step's end"]


def test_sigterm_ends_a_command_as_ctrl_c_does(tmp_path, monkeypatch, capsys, request):
    """SIGTERM (``kill``, a scheduler's stop) inside a step waits for the step's end, as
    Ctrl-C does, and the command ends saying so, with status 143 (the default action ended
    the process without a word, skipping what Ctrl-C's handling keeps); outside commands
    SIGTERM keeps its own handling."""
    import signal

    from gridsim import interrupts
    from gridsim.cli import main
    from gridsim.world.scripted_drivers import LaneFollower

    before = signal.signal(signal.SIGTERM, signal.SIG_DFL)  # (as in a command's process:
    request.addfinalizer(lambda: signal.signal(signal.SIGTERM, before))  # ray sets its own)
    with interrupts.deferred():
        # (checked first: without the handler a SIGTERM would end the test session)
        assert signal.getsignal(signal.SIGTERM) is interrupts._handler
        interrupts.enter()
        os.kill(os.getpid(), signal.SIGTERM)
        with pytest.raises(interrupts.Terminated):
            interrupts.leave()
        with pytest.raises(KeyboardInterrupt):  # (a kind of Ctrl-C's)
            os.kill(os.getpid(), signal.SIGTERM)
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL  # put back
    ignored = signal.signal(signal.SIGINT, signal.SIG_IGN)  # a shell's background job
    try:
        with interrupts.deferred():  # (SIGTERM was left to kill it there)
            assert signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL
    finally:
        signal.signal(signal.SIGINT, ignored)
    calls = []
    drive = LaneFollower.__call__

    def signalled(self, world):  # a SIGTERM as the 20th tick is computed
        calls.append(1)
        if len(calls) == 20:
            assert signal.getsignal(signal.SIGTERM) is interrupts._handler  # (see above)
            os.kill(os.getpid(), signal.SIGTERM)
        return drive(self, world)

    monkeypatch.setattr(LaneFollower, "__call__", signalled)
    assert main(["drive", "--out", str(tmp_path / "d"), "--quiet"]) == 143
    assert capsys.readouterr().err.strip().endswith("gridsim: terminated (SIGTERM)")
    assert len(calls) == 20 and not (tmp_path / "d").exists()
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL


def test_a_full_disk_is_named_not_called_a_bug(capsys):
    import errno

    def full(args):
        raise OSError(errno.ENOSPC, "No space left on device", "/runs/x/checkpoint.npz")

    assert run_command(_parser(full), []) == 2
    err = capsys.readouterr().err
    assert "gridsim: error: /runs/x/checkpoint.npz: No space left on device; free some" in err
    assert "internal error" not in err


def test_an_unknown_flag_is_refused_with_its_subcommands_usage(capsys):
    """``gridsim run --polcy``: the usage shown is ``gridsim run``'s, whose flags the user
    was after (it was the top-level usage, which lists only the subcommands)."""
    import pytest

    from gridsim.cli import main as gridsim_main
    from neurotrajectory.cli import main as nt_main

    for main, argv, usage in ((gridsim_main, ["run", "--polcy", "x"], "usage: gridsim run "),
                              (nt_main, ["heldout", "--run", "r", "--out", "o", "--bogus"],
                               "usage: neurotrajectory heldout ")):  # fmt: skip
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert err.startswith(usage) and "unrecognized arguments: --" in err


def test_subcommand_help_states_the_defaults():
    """Every option with a default says it in its help entry: by its own text or the
    formatter's."""
    from gridsim.cli import build_parser as gridsim_parser
    from neurotrajectory.cli import build_parser as nt_parser

    for build in (gridsim_parser, nt_parser):
        sub = next(a for a in build()._actions if isinstance(a, argparse._SubParsersAction))
        for name, parser in sub.choices.items():
            for action in parser._actions:
                shown = action.option_strings and action.help != argparse.SUPPRESS
                if shown and action.default not in (None, False, True, argparse.SUPPRESS):
                    entry = parser._get_formatter()._format_action(action)
                    assert "default" in entry, f"{name}: {entry}"
    run = sub_parser(gridsim_parser(), "run")._get_formatter()
    seed = next(
        a for a in sub_parser(gridsim_parser(), "run")._actions if "--seed" in a.option_strings
    )
    assert " ".join(run._format_action(seed).split()) == "--seed SEED episode seed (default 0)"


def sub_parser(parser: argparse.ArgumentParser, name: str) -> argparse.ArgumentParser:
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[name]


def test_a_flag_error_says_a_path_once():
    """An error about a flag's path that names the path itself does not get it again; other
    values (a scenario name) stay beside their flag."""
    from gridsim.errors import flagged

    said = flagged("--scenario", "/tmp/x.yaml", "/tmp/x.yaml: invalid scenario")
    assert said == "--scenario: /tmp/x.yaml: invalid scenario"
    assert flagged("--pretrain", "data/hw", "data/hw is not a dataset") == \
        "--pretrain: data/hw is not a dataset"  # fmt: skip
    assert (
        flagged("--scenario", "seamless", "seamless: bad road")
        == "--scenario seamless: seamless: bad road"
    )  # a name, not a path: kept
    assert flagged("--pretrain", "data/hw", "no windows") == "--pretrain data/hw: no windows"
    # another file whose name ends in the value's: not the value
    assert flagged("--scenario", "a.yaml", "data.yaml: bad") == "--scenario a.yaml: data.yaml: bad"


def test_a_data_warning_under_a_progress_bar_starts_its_own_line(capsys):
    """A warning that arrives while a command's progress bar is drawn clears the bar first
    (it was glued to the bar's line: '...?episode/s]neurotrajectory: warning: ...')."""
    import sys

    from tqdm import tqdm

    from gridsim.cli.command import _show_warning
    from gridsim.errors import DataWarning

    with tqdm(desc="record x", unit="episode", file=sys.stderr, mininterval=0) as bar:
        bar.refresh()
        _show_warning("neurotrajectory", set(), "a flawed track", DataWarning, "f", 1)
    err = capsys.readouterr().err
    before = err[: err.index("neurotrajectory: warning: a flawed track")]
    assert before.endswith(("\r", "\n")) and "episode" in before


def test_run_prints_its_summary_rounded(capsys):
    """``gridsim run`` prints four significant digits (it printed ``159.2723388671875``);
    the rounding keeps ints, booleans and strings, and a tiny float stays a float."""
    import json

    from gridsim.cli import main
    from gridsim.outputs import rounded

    assert rounded({"a": [159.2723388671875, 1.0535299195535419e-11], "n": 3, "b": True}) == {
        "a": [159.3, 1.054e-11], "n": 3, "b": True}  # fmt: skip
    assert rounded([12345.6, -7.96361, 0.0]) == [12346.0, -7.964, 0.0]  # whole digits kept
    assert main(["run", "--scenario", "seamless", "--steps", "5", "--quiet"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["steps"] == 5 and summary["collision"] is False
    figures = [summary["mean_speed"], *summary["fitness_sums"].values()]
    assert all(x == float(f"{x:.4g}") for x in figures)


def test_both_commands_say_their_version(capsys):
    from gridsim import __version__
    from gridsim.cli import main as gridsim_main
    from neurotrajectory.cli import main as nt_main

    for main, prog in ((gridsim_main, "gridsim"), (nt_main, "neurotrajectory")):
        with pytest.raises(SystemExit) as exc:
            main(["--version"])
        assert exc.value.code == 0 and capsys.readouterr().out == f"{prog} {__version__}\n"
