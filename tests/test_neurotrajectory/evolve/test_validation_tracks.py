"""Validation on held-out training tracks (``train --validation-tracks SHARE``): on a recorded
scene, a share of the training tracks is kept out of evolution, and the learning curve and the
final front are chosen on episodes that drive them."""

import numpy as np
import pytest

from neurotrajectory.evolve.backends import LocalBackend, WorkerSpec
from neurotrajectory.evolve.genome import initial_genome
from neurotrajectory.evolve.runs import Run, RunError, TrainConfig
from neurotrajectory.model import PRESETS, TrajectoryNet

TRACKS = ("381", "384", "388", "389", "394", "395", "399", "400", "405", "422")


def test_the_held_tracks_are_a_seeded_share_kept_out_of_the_generations():
    cfg = TrainConfig(scenario="us101_4_1", preset="tiny", ego_tracks=TRACKS,
                      validation_tracks=0.3, seed=7)  # fmt: skip
    held = cfg.held_tracks
    assert len(held) == 3 and set(held) < set(TRACKS)
    assert held == TrainConfig(**{**cfg.__dict__}).held_tracks  # a function of the seed
    assert held != TrainConfig(**{**cfg.__dict__, "seed": 8}).held_tracks
    trained = cfg.overrides["ego"]["track"]
    assert sorted(trained + list(held)) == sorted(TRACKS) and not set(trained) & set(held)
    assert cfg.validation_overrides["ego"]["track"] == list(held)
    assert cfg.validation_overrides["simulation"] == cfg.overrides["simulation"]
    # at least one held, at least one trained
    assert len(TrainConfig(ego_tracks=TRACKS[:2], validation_tracks=0.1).held_tracks) == 1
    assert len(TrainConfig(ego_tracks=TRACKS[:2], validation_tracks=0.9).held_tracks) == 1
    plain = TrainConfig(scenario="us101_4_1", ego_tracks=TRACKS)
    assert plain.held_tracks == () and plain.validation_overrides is None
    assert plain.overrides["ego"]["track"] == list(TRACKS)


@pytest.mark.parametrize(
    ("share", "tracks", "message"),
    [
        (1.0, TRACKS, r"validation_tracks must be a finite number in \[0, 1\), got"),
        (-0.1, TRACKS, r"validation_tracks must be a finite number in \[0, 1\), got"),
        ("0.3", TRACKS, r"validation_tracks must be a finite number in \[0, 1\), got"),
        (0.3, ("381",), "needs a scene with at least 2 training tracks"),
        (0.3, ("a/1", "b/2"), "needs a scene with at least 2 training tracks"),
    ],
)
def test_a_bad_share_is_refused_saying_why(share, tracks, message):
    with pytest.raises(RunError, match=message):
        TrainConfig(ego_tracks=tracks, validation_tracks=share)
    with pytest.raises(RunError, match="give --validation-episodes >= 1"):
        TrainConfig(ego_tracks=TRACKS, validation_tracks=0.3, validation_episodes=0)


def test_every_scene_of_a_collection_keeps_tracks_on_both_sides():
    names = tuple(f"us101_4_1/{i}" for i in range(14)) + ("us101_3_3/1", "us101_3_3/2",
                                                          "us101_3_3/3", "lonely/9")  # fmt: skip
    for seed in range(50):
        cfg = TrainConfig(ego_tracks=names, validation_tracks=0.3, seed=seed)
        held = set(cfg.held_tracks)
        trained = set(cfg.overrides["ego"]["track"])
        for scene in ("us101_4_1/", "us101_3_3/"):
            assert any(t.startswith(scene) for t in held), (seed, scene)
            assert any(t.startswith(scene) for t in trained), (seed, scene)
        assert "lonely/9" in trained and len([t for t in held if "4_1" in t]) == 4


def test_a_scene_without_training_tracks_cannot_hold_any_out(tmp_path):
    with pytest.raises(RunError, match="--validation-tracks 0.3 holds out some of the training "
                       "tracks of a recorded scene"):  # fmt: skip
        Run.create(tmp_path / "run", TrainConfig(preset="tiny", validation_tracks=0.3))
    assert not (tmp_path / "run").exists()


def test_validation_episodes_drive_only_the_held_tracks():
    trained, held = TRACKS[:7], TRACKS[7:]
    short = {"simulation": {"duration": 1.0}}
    spec = WorkerSpec("us101_4_1", {**short, "ego": {"track": list(trained)}}, PRESETS["tiny"],
                      (2, 4), batch=2,
                      validation_overrides={**short, "ego": {"track": list(held)}})  # fmt: skip
    backend = LocalBackend(spec)
    net = TrajectoryNet(backend.worker.evaluator.net_cfg)
    backend.load(np.stack([initial_genome(net, s) for s in range(2)]))
    seeds = tuple(range(0, 24, 2))
    backend.evaluate(2, seeds)
    backend.evaluate(2, seeds, validation=True)
    worker = backend.worker
    drove = {env.world.ego_track.track_id for env in worker.evaluator.envs}
    validated = {env.world.ego_track.track_id for env in worker._validator.envs}
    assert drove <= set(trained) and validated <= set(held) and len(validated) > 1
    fit, _ = backend.evaluate_members([1, 0], seeds, validation=True)
    again, _ = backend.evaluate(2, seeds, validation=True)
    assert np.array_equal(fit, again[[1, 0]])
