"""Typed settings: the trainer's and the evaluation's configurations validated like the
scenario schema, with every problem named (field, value, what is expected)."""

import numpy as np
import pytest

from neurotrajectory.compare.baselines.end2end import TrainSettings
from neurotrajectory.compare.evaluation import EvalConfig
from neurotrajectory.data.windows import DatasetError
from neurotrajectory.evolve.runs import Run, RunError, TrainConfig
from neurotrajectory.model import PRESETS


@pytest.mark.parametrize(
    ("given", "message"),
    [
        ({"population": 1}, "population must be an integer >= 2, got 1"),
        ({"population": True}, "population must be an integer >= 2, got True"),
        ({"population": 2.0}, "population must be an integer >= 2, got 2.0"),
        ({"generations": "3"}, "generations must be an integer >= 1, got '3'"),
        ({"sigma": 0}, r"sigma must be a finite number in \(0, 10\], got 0"),
        ({"sigma": float("nan")}, r"sigma must be a finite number in \(0, 10\], got nan"),
        ({"es_step": "2"}, r"es_step must be a finite number in \(0, 100\], got '2'"),
        ({"plan_smoothing": 1.0}, r"plan_smoothing must be a finite number in \[0, 1\), got 1.0"),
        ({"seed": -1}, r"seed must be an integer in \[0, 9223372036854775807\], got -1"),
        ({"preset": "huge"}, r"unknown preset 'huge'; choose from \['paper', 'default', 'tiny'\]"),
        ({"evolve": "cnn"}, r"unknown evolve scope 'cnn'; choose from \['all', 'head'"),
        ({"frame": "world"}, r"unknown frame 'world'; choose from \['ego', 'grid'\]"),
        (
            {"populaton": 8},
            "unknown setting 'populaton' of TrainConfig "
            r"\(did you mean 'population'\?\)",
        ),  # fmt: skip
        ({"max_correction": (1.0,)}, r"max_correction must be two finite numbers > 0"),
        ({"skip": "no"}, "skip must be true or false, got 'no'"),
        ({"skip": 2}, "skip must be true or false, got 2"),
        ({"ego_tracks": "381"}, "ego_tracks: input should be a valid tuple, got '381'"),
    ],
)
def test_a_wrong_setting_is_named_with_its_value_and_range(given, message):
    with pytest.raises(RunError, match=message):
        TrainConfig(**given)


def test_every_problem_is_reported_at_once_and_checks_across_fields_follow():
    with pytest.raises(RunError) as info:
        TrainConfig(population=0, sigma=-1.0, backend="gpu")
    said = str(info.value)
    assert said.startswith("3 problems: ")
    for part in ("population must be", "sigma must be", "unknown backend 'gpu'"):
        assert part in said
    # checks across fields, each field valid on its own: every one that fails, in its words
    with pytest.raises(RunError) as info:
        TrainConfig(dagger_rounds=1, evolve="head")
    said = str(info.value)
    assert said.startswith("2 problems: --dagger-rounds refit the warm start")
    assert "; --evolve head keeps the warm start's encoder" in said


def test_numbers_are_strict_but_take_numpy_scalars_and_keep_what_was_given():
    cfg = TrainConfig(population=np.int64(6), sigma=np.float32(0.25), episode_seconds=10)
    assert cfg.population == 6 and type(cfg.population) is int
    assert cfg.sigma == 0.25 and type(cfg.sigma) is float
    # a whole number stays as given (config.json and the run's identity keep it)
    assert cfg.episode_seconds == 10 and type(cfg.episode_seconds) is int
    assert cfg == cfg.replace(episode_seconds=10.0) and cfg.as_dict()["episode_seconds"] == 10
    with pytest.raises(RunError, match="population must be an integer"):
        TrainConfig(population=np.bool_(True))
    # switches saved as 0 and 1 (by hand, or by the dataclass TrainConfig) read as booleans
    assert TrainConfig(skip=0).skip is False and TrainConfig(constrained=1).constrained is True
    # track ids from any collection of them, as names
    for ids in ([3, 4], np.array([3, 4]), range(3, 5), ("3", "4")):
        assert TrainConfig(ego_tracks=ids).ego_tracks == ("3", "4")


def test_settings_are_frozen_and_replace_validates_again():
    cfg = TrainConfig(population=6)
    with pytest.raises(ValueError, match="frozen"):
        cfg.population = 8
    assert cfg.replace(population=8).population == 8
    with pytest.raises(RunError, match="population must be an integer >= 2"):
        cfg.replace(population=1)
    assert cfg.replace() == cfg and hash(cfg.replace()) == hash(cfg)


def test_choices_are_read_from_the_registry_when_checked(monkeypatch):
    """A preset registered after the settings were defined is a valid choice."""
    monkeypatch.setitem(PRESETS, "mine", PRESETS["tiny"])
    assert TrainConfig(preset="mine").activation == PRESETS["tiny"].activation


def test_config_round_trips_and_keeps_the_fingerprints_of_runs_saved_before():
    """``as_dict`` (what config.json holds) builds the same configuration; and the run's
    fingerprint (its identity in every checkpoint) is the one the dataclass TrainConfig
    gave, so runs saved before the typed settings still resume."""
    cfgs = [
        TrainConfig(),
        TrainConfig(
            scenario="inner_city",
            pretrain_episodes=12,
            activation="tanh",
            max_correction=(8, 3),
            goal_seconds=5.0,
        ),  # fmt: skip
        TrainConfig(
            ego_tracks=("1", "2", "3"),
            validation_tracks=0.3,
            pretrain="x",
            evolve="readout",
            selection="es",
        ),  # fmt: skip
    ]
    cfgs += [  # whole numbers given to number settings: saved as given, before and now
        TrainConfig(es_step=3),
        TrainConfig(preset="tiny", population=4, episode_seconds=20, goal_seconds=5),
        TrainConfig(
            sigma=1,
            plan_smoothing=0,
            pretrain_episodes=2,
            dagger_rounds=1,
            dagger_weight=1,
            pretrain_validation=0,
        ),  # fmt: skip
    ]
    for cfg in cfgs:
        assert TrainConfig(**cfg.as_dict()) == cfg
    # measured with the dataclass TrainConfig (commit 11b67f1)
    before = ["648415b897744a40", "a3a1fe706f31df29", "5a74ba040d1da730", "709de1bbe58be563",
              "51e14fbae6d97ee1", "5cc1465c3b0b0b7e"]  # fmt: skip
    assert [Run("unused", cfg).fingerprint for cfg in cfgs] == before
    assert cfgs[1].max_correction == (8.0, 3.0) and cfgs[2].ego_tracks == ("1", "2", "3")


def test_eval_config_and_end2end_settings_name_their_problems():
    with pytest.raises(DatasetError, match=r"closed_loop_seconds must be a finite number in "
                       r"\(0, 3600\], got 0"):  # fmt: skip
        EvalConfig(closed_loop_seconds=0)
    with pytest.raises(DatasetError, match=r"unknown pick 'middle'; choose from \['knee'"):
        EvalConfig(pick="middle")
    with pytest.raises(DatasetError, match=r"unknown scenario groups \['mine'\]"):
        EvalConfig(groups=("mine",))
    assert EvalConfig(groups=("mine",), sources={"mine": "x/*.yaml"}).groups == ("mine",)
    with pytest.raises(DatasetError, match="end2end.epochs must be an integer >= 1, got 0"):
        EvalConfig(end2end={"epochs": 0})
    with pytest.raises(DatasetError, match="end2end.epochs must be an integer >= 1, got 0; "
                       "end2end.learning_rate must be a finite number > 0, got -1"):  # fmt: skip
        EvalConfig(end2end={"epochs": 0, "learning_rate": -1})
    with pytest.raises(ValueError, match="epochs must be an integer >= 1, got 0"):
        TrainSettings(epochs=0)
    assert EvalConfig().as_dict()["end2end"] == {"epochs": 8, "batch_size": 32,
                                                 "learning_rate": 1e-3, "seed": 0}  # fmt: skip
