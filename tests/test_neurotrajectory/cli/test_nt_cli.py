"""The ``neurotrajectory`` command line: flags declared once, defaults read from the configs."""

from dataclasses import fields

from neurotrajectory.cli import build_parser, main
from neurotrajectory.cli.evaluate import EVAL
from neurotrajectory.evolve.runs import TrainConfig


def _subparser(name: str):
    return next(a for a in build_parser()._actions if a.dest == "command").choices[name]


def test_train_flags_show_the_config_defaults_and_leave_them_to_it():
    """Every train flag of a TrainConfig field parses to None when left out (the field's
    default applies; a resumed run can tell given from not given), and its help states the
    field's default, so that a default changed in TrainConfig shows in --help."""
    defaults = {f.name: f.default for f in fields(TrainConfig)}
    train = _subparser("train")
    checked = 0
    for action in train._actions:
        if action.dest not in defaults:
            continue
        assert action.default is None, action.option_strings
        value = defaults[action.dest]
        if value is None or isinstance(value, bool) or action.dest == "ego_tracks":
            continue
        shown = f"{value:g}" if isinstance(value, float) else str(value)
        assert f"default {shown}" in action.help, (action.option_strings, action.help)
        checked += 1
    assert checked >= 15


def test_evaluate_flags_default_to_the_eval_config():
    args = _subparser("evaluate").parse_args(["--run", "r", "--out", "o"])
    for name in ("episodes", "episode_seconds", "test_fraction", "closed_loop_episodes",
                 "closed_loop_seconds", "seed", "pick"):  # fmt: skip
        assert getattr(args, name) == getattr(EVAL, name), name


def test_record_group_is_now_name_and_says_so(tmp_path, capsys):
    """The dataset's group name moved from ``record --group`` to ``record --name`` (``--group``
    is evaluate's NAME=FOLDER); the old spelling is refused naming the new one, and nothing
    is written."""
    out = tmp_path / "data"
    assert main(["record", "--scenario", "seamless", "--group", "mine", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--name mine" in err and "evaluate" in err
    assert not out.exists()
