"""The ``neurotrajectory`` command line: flags declared once, defaults read from the configs."""

from neurotrajectory.cli import build_parser, main
from neurotrajectory.compare.evaluation import EvalConfig
from neurotrajectory.evolve.runs import TrainConfig


def _subparser(name: str):
    return next(a for a in build_parser()._actions if a.dest == "command").choices[name]


def test_train_flags_show_the_config_defaults_and_leave_them_to_it():
    """Every train flag of a TrainConfig field parses to None when left out (the field's
    default applies; a resumed run can tell given from not given), and its help states the
    field's default, so that a default changed in TrainConfig shows in --help; the help is the
    field's description (written once, in TrainConfig)."""
    defaults = TrainConfig.defaults()
    train = _subparser("train")
    checked = 0
    for action in train._actions:
        if action.dest not in defaults:
            continue
        assert action.default is None, action.option_strings
        value = defaults[action.dest]
        if value is None or isinstance(value, bool) or action.dest == "ego_tracks":
            continue
        shown = f"{value:g}" if isinstance(value, float) else (
            repr(value) if isinstance(value, str) else str(value))  # fmt: skip
        assert f"default {shown}" in action.help, (action.option_strings, action.help)
        assert action.help.startswith(TrainConfig.model_fields[action.dest].description)
        checked += 1
    assert checked >= 15


def test_train_flags_parse_within_the_fields_bounds_and_choices(capsys):
    """An integer flag takes the field's minimum, a choice flag the field's choices: argparse
    refuses the rest naming the flag, before any work."""
    train = _subparser("train")
    for bad, said in ((["--population", "1"], "expected an integer >= 2"),
                      (["--preset", "huge"], "invalid choice: 'huge'"),
                      (["--evolve", "cnn"], "invalid choice: 'cnn'")):  # fmt: skip
        try:
            train.parse_args(bad)
        except SystemExit as exc:
            assert exc.code == 2
        assert said in capsys.readouterr().err, bad


def test_evaluate_flags_default_to_the_eval_config(monkeypatch, tmp_path):
    """A flag left out is None and the EvalConfig's default applies; the configuration
    evaluate builds from no flags is EvalConfig's own."""
    args = _subparser("evaluate").parse_args(["--run", "r", "--out", "o"])
    for name in ("episodes", "episode_seconds", "test_fraction", "closed_loop_episodes",
                 "closed_loop_seconds", "seed", "pick"):  # fmt: skip
        assert getattr(args, name) is None, name
    built = {}
    monkeypatch.setattr("neurotrajectory.compare.evaluation.evaluate",
                        lambda run, out, cfg, **kw: built.update(cfg=cfg))  # fmt: skip
    (tmp_path / "table2.md").write_text("")
    main(["evaluate", "--run", "r", "--out", str(tmp_path)])
    assert built["cfg"] == EvalConfig()
    main(["evaluate", "--run", "r", "--out", str(tmp_path), "--seed", "4", "--e2e-epochs", "2",
          "--episodes", "3"])  # fmt: skip
    assert built["cfg"] == EvalConfig(seed=4, episodes=3, end2end={"epochs": 2, "seed": 4})


def test_record_of_a_misspelt_group_names_the_groups_and_writes_nothing(tmp_path, capsys):
    """``--scenario highwy``: refused before the progress bar and the output folder, with
    the groups listed beside the built-in scenarios and the group it resembles."""
    out = tmp_path / "data" / "x"
    assert main(["record", "--scenario", "highwy", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "unknown scenario 'highwy'" in err and "or a group: seamless, inner_city" in err
    assert "did you mean the group 'highway'?" in err and "episode" not in err
    assert not (tmp_path / "data").exists()


def test_record_group_is_now_name_and_says_so(tmp_path, capsys):
    """The dataset's group name moved from ``record --group`` to ``record --name`` (``--group``
    is evaluate's NAME=FOLDER); the old spelling is refused naming the new one, and nothing
    is written."""
    out = tmp_path / "data"
    assert main(["record", "--scenario", "seamless", "--group", "mine", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--name mine" in err and "evaluate" in err
    assert not out.exists()


def test_ctrl_c_while_the_trainer_loads_is_no_crash(monkeypatch, capsys):
    """The command loads torch and the trainer for a second or two before it parses its
    arguments: a Ctrl-C then says "interrupted" (status 130), not a Python traceback."""
    import sys

    from neurotrajectory import __main__ as entry

    class Loading:
        def __getattr__(self, name):
            raise KeyboardInterrupt

    monkeypatch.setitem(sys.modules, "neurotrajectory.cli", Loading())
    assert entry.main(["--help"]) == 130
    assert capsys.readouterr().err == "neurotrajectory: interrupted\n"
