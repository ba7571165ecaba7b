"""Front members and the warm start loaded from a run folder."""

import warnings

import pytest


def test_a_removed_warm_start_is_said_not_dropped_silently(tmp_path):
    """A run trained from a warm start whose warm_start.npz was removed: its held-out report
    silently lost the warm start's comparison; now a warning says so (a run without a warm
    start says nothing)."""
    from types import SimpleNamespace

    from gridsim.errors import DataWarning
    from neurotrajectory.compare.front import load_warm_start
    from neurotrajectory.evolve.runs import TrainConfig

    def run(pretrain_episodes):
        config = TrainConfig(pretrain_episodes=pretrain_episodes)
        return SimpleNamespace(out=tmp_path, config=config, warm_start_genome=lambda: None)

    with pytest.warns(DataWarning, match=r"warm_start\.npz is missing: the run's warm start"):
        assert load_warm_start(run(12)) is None
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_warm_start(run(0)) is None


def test_a_run_still_training_is_said_to_be_so_not_to_be_resumed(tmp_path):
    """``heldout`` / ``rollout`` of a run another process is training said "train --resume
    RUN chooses it", which the lock refuses: now that the run is being trained, and by whom."""
    from gridsim.outputs import folder_holder, folder_lock
    from neurotrajectory.compare.front import load_front
    from neurotrajectory.evolve.runs import Run, RunError, TrainConfig

    run = Run.create(tmp_path / "run", TrainConfig(preset="tiny"))
    assert folder_holder(run.out) is None
    with pytest.raises(RunError, match="train --resume"):
        load_front(run.out)
    with folder_lock(run.out):
        assert folder_holder(run.out).startswith("pid ")
        with pytest.raises(RunError, match=r"no front.npz yet: the run is being trained \(pid "):
            load_front(run.out)
    assert folder_holder(run.out) is None
