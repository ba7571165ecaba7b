"""Warm-starting neuroevolution by fitting the network to recorded windows."""

import json
import tempfile
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest
from breaks import ctrl_c_at

from neurotrajectory.cli import main
from neurotrajectory.data.storage import load_dataset, save_dataset
from neurotrajectory.data.windows import (
    DatasetError,
    Windows,
    drive_windows,
    episodes_of,
    record_group,
    record_scenario,
    rejoin_labels,
    scenario_episodes,
    split_by_track,
)
from neurotrajectory.evolve.genome import initial_genome, mutation_mask
from neurotrajectory.evolve.runs import Run, RunError, TrainConfig
from neurotrajectory.evolve.warm_start import (
    PretrainError,
    fit_skip,
    pretrain_genome,
    setpoint_mse,
    visited_weights,
)
from neurotrajectory.model import PRESETS, NetConfig, TrajectoryNet

#: Training runs, rollouts or subprocesses: left out of the quick loop (`pytest -m "not slow"`).
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def windows_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("pre") / "seamless"
    save_dataset(record_group("seamless", 2, seed=9, duration=6.0), out)
    return out


def _tiny_net(skip=True):  # on the constant-velocity prior: much to fit
    sizes = {"grid_size": 128, "prior": "constant_velocity", "skip": skip}
    return TrajectoryNet(NetConfig(**{**PRESETS["tiny"].to_dict(), **sizes}))


def test_pretraining_fits_the_windows_deterministically(windows_dir):
    w = load_dataset(windows_dir).windows
    net = _tiny_net()
    start = initial_genome(net, 3)
    a, stats = pretrain_genome(net, start, w, epochs=10, seed=0, learning_rate=1e-2)
    b, _ = pretrain_genome(_tiny_net(), start, w, epochs=10, seed=0, learning_rate=1e-2)
    np.testing.assert_array_equal(a, b)
    assert stats["mse_after"] < 0.8 * stats["mse_before"]
    assert setpoint_mse(net, w) == pytest.approx(stats["mse_after"])
    with pytest.raises(PretrainError, match=r"pre-training: .*\(history, grid size, horizon\)"):
        small = TrajectoryNet(NetConfig(**{**PRESETS["tiny"].to_dict(), "grid_size": 64}))
        pretrain_genome(small, initial_genome(small, 0), w, epochs=1, seed=0)


def test_grids_bigger_than_the_memory_are_read_into_a_scratch_file(windows_dir, tmp_path,
                                                                   monkeypatch):  # fmt: skip
    """A dataset whose grids would take more than half the memory available is read into a
    scratch file and mapped (the operating system keeps what fits in memory): the same
    windows, the same fit bit for bit (DAgger's concatenation too), a note that says where,
    and no file left behind; a scratch folder missing or without room is named in a clear
    error; where the memory available cannot be told, grids stay in memory."""
    from gridsim.errors import DataWarning
    from neurotrajectory.data import scratch, storage
    from neurotrajectory.data.windows import DatasetError, Windows

    in_memory = load_dataset(windows_dir).windows
    folder = tmp_path / "scratch"
    folder.mkdir()
    monkeypatch.setenv(scratch.SCRATCH_ENV, str(folder))
    monkeypatch.setattr(scratch, "MEMORY_SHARE", 0.0)
    with pytest.warns(DataWarning, match=f"read into a scratch file in {folder}"):
        mapped = load_dataset(windows_dir).windows
    assert isinstance(mapped.grids, np.memmap) and list(folder.iterdir()) == []
    for f in fields(mapped):
        np.testing.assert_array_equal(getattr(mapped, f.name), getattr(in_memory, f.name))
    start = initial_genome(_tiny_net(), 3)
    fits = [pretrain_genome(_tiny_net(), start, w, epochs=2, seed=0, validation=0.5)[0]
            for w in (in_memory, mapped)]  # fmt: skip
    np.testing.assert_array_equal(*fits)
    visited = in_memory.take(np.arange(0, len(in_memory), 3))  # (as DAgger concatenates)
    with pytest.warns(DataWarning, match="the warm start's windows: its grids take"):
        joined = scratch.concat_windows([mapped.select(np.arange(5, 20)), visited],
                                        "the warm start's windows")  # fmt: skip
    expected = Windows.concat([in_memory.take(np.arange(5, 20)), visited])
    assert isinstance(joined.grids, np.memmap)
    for f in fields(joined):
        np.testing.assert_array_equal(getattr(joined, f.name), getattr(expected, f.name))
    with pytest.warns(DataWarning, match="read into a scratch file"):  # both sides of a split
        _, *sides = storage.load_split(windows_dir, 0.5, 0)
    for side, split in zip(sides, split_by_track(in_memory, 0.5, 0), strict=True):
        assert isinstance(side.grids, np.memmap)
        np.testing.assert_array_equal(side.grids, split.grids)
    monkeypatch.setattr(scratch, "memory_available", lambda: None)  # (macOS, Windows)
    assert not isinstance(load_dataset(windows_dir).windows.grids, np.memmap)
    monkeypatch.undo()
    monkeypatch.setattr(scratch, "MEMORY_SHARE", 0.0)
    monkeypatch.setenv(scratch.SCRATCH_ENV, str(tmp_path / "none"))
    with pytest.raises(DatasetError, match=f"{scratch.SCRATCH_ENV} names {tmp_path / 'none'}, "
                       "which is not a folder"):  # fmt: skip
        load_dataset(windows_dir)
    monkeypatch.setenv(scratch.SCRATCH_ENV, str(folder))
    monkeypatch.setattr(scratch.tempfile, "TemporaryFile", _refused)  # (a folder not ours)
    with pytest.raises(DatasetError, match=f"a scratch file of that size in {folder} failed "
                       r"\(Permission denied\): set NEUROTRAJECTORY_SCRATCH"):  # fmt: skip
        load_dataset(windows_dir)
    monkeypatch.undo()
    monkeypatch.setattr(scratch, "MEMORY_SHARE", 0.0)
    monkeypatch.setenv(scratch.SCRATCH_ENV, str(folder))
    monkeypatch.setattr(scratch.shutil, "disk_usage", lambda _: type("U", (), {"free": 10})())
    with pytest.raises(DatasetError, match=f"more than the free space of the scratch folder "
                       f"{folder} .*set {scratch.SCRATCH_ENV} to a folder with room"):  # fmt: skip
        load_dataset(windows_dir)


def _refused(*args, **kwargs):
    raise PermissionError(13, "Permission denied")


def test_the_scratch_folder_is_not_one_kept_in_memory(tmp_path, monkeypatch):
    """Scratch files go to the temporary folder, unless it lives in memory (tmpfs): then
    beside the dataset; a folder named in the environment wins."""
    from neurotrajectory.data import scratch

    monkeypatch.delenv(scratch.SCRATCH_ENV, raising=False)
    dataset = tmp_path / "data"
    dataset.mkdir()
    monkeypatch.setattr(scratch, "_in_memory", lambda folder: False)
    assert scratch.scratch_folder(dataset) == Path(tempfile.gettempdir())
    monkeypatch.setattr(scratch, "_in_memory", lambda folder: True)
    assert scratch.scratch_folder(dataset) == dataset
    assert scratch.scratch_folder(dataset / "manifest.json") == dataset
    monkeypatch.setenv(scratch.SCRATCH_ENV, str(tmp_path))
    assert scratch.scratch_folder(dataset) == tmp_path
    if Path("/proc/mounts").is_file() and Path("/dev/shm").is_dir():  # Linux: shared memory
        monkeypatch.undo()
        assert scratch._in_memory(Path("/dev/shm"))


def test_the_epoch_kept_is_the_one_that_predicts_held_out_tracks_best(windows_dir):
    w = load_dataset(windows_dir).windows
    net = _tiny_net()
    start = initial_genome(net, 3)
    genome, stats = pretrain_genome(net, start, w, epochs=6, seed=0, learning_rate=1e-2,
                                    validation=0.5)  # fmt: skip
    scores = stats["validation_mse"]
    assert len(scores) == 7 and stats["best_epoch"] == int(np.argmin(scores))
    assert stats["validation_windows"] + stats["windows"] == len(w)
    fit, held_out = split_by_track(w, 0.5, 0)
    assert setpoint_mse(net, held_out) == pytest.approx(min(scores))
    # a fit that only gets worse on held-out tracks (a diverging step) keeps the start (here
    # without the skip read-out, whose closed-form fit would be epoch 0)
    plain = _tiny_net(skip=False)
    start = initial_genome(plain, 3)
    kept, stats = pretrain_genome(plain, start, w, epochs=2, seed=0, learning_rate=100.0,
                                  validation=0.5)  # fmt: skip
    scores = stats["validation_mse"]
    assert stats["best_epoch"] == 0 and min(scores[1:]) > scores[0]
    np.testing.assert_array_equal(kept, start)
    with pytest.raises(PretrainError, match="needs windows of >= 2 tracks"):
        one = w.take(np.flatnonzero(w.track == w.track[0]))
        pretrain_genome(_tiny_net(), start, one, epochs=1, seed=0, validation=0.2)
    with pytest.raises(RunError, match="--pretrain-episodes 1 leaves no episode"):
        TrainConfig(pretrain_episodes=1)


def test_a_warm_started_run_begins_from_the_fitted_network(windows_dir, tmp_path):
    out = tmp_path / "run"
    args = ["train", "--preset", "tiny", "--population", "4", "--generations", "2",
            "--episodes", "1", "--episode-seconds", "3", "--pretrain", str(windows_dir),
            "--pretrain-epochs", "2", "--out", str(out), "--quiet"]  # fmt: skip
    assert main(args) == 0
    stats = json.loads((out / "pretrain.json").read_text())
    assert stats["mse_after"] < stats["mse_before"] and stats["windows"] > 0
    run = Run.open(out)
    assert run.config.pretrain == str(windows_dir) and run.config.pretrain_epochs == 2
    # generation 0, individual 0 is the fitted network itself
    history = json.loads((out / "history.json").read_text())["generations"]
    assert len(history) == 2
    again = tmp_path / "again"
    assert main([*args[:-3], "--out", str(again), "--quiet"]) == 0
    assert (
        json.loads((again / "history.json").read_text())["generations"][0]["fitness"]
        == (history[0]["fitness"])
    )


@pytest.mark.parametrize("scope", ["head", "readout"])
def test_evolving_the_head_keeps_the_warm_started_encoder(windows_dir, tmp_path, scope):
    out = tmp_path / scope
    args = ["train", "--preset", "tiny", "--population", "4", "--generations", "3",
            "--episodes", "1", "--episode-seconds", "2", "--pretrain", str(windows_dir),
            "--pretrain-epochs", "2", "--evolve", scope, "--sigma", "0.05", "--heldout", "0",
            "--out", str(out), "--quiet"]  # fmt: skip
    assert main(args) == 0
    with np.load(out / "checkpoint.npz") as ckpt:
        population = ckpt["population"]
    run = Run.open(out)
    net = TrajectoryNet(run.net_config)
    evolved = net.evolved(scope)
    names = {"head": {"branches.weight_ih", "branches.weight_hh", "branches.bias_ih",
                      "branches.bias_hh", "branches.head_weight", "branches.head_bias",
                      "skip_weight"},
             "readout": {"branches.head_weight", "branches.head_bias", "skip_weight"}}  # fmt: skip
    assert set(evolved) == names[scope]
    mask = mutation_mask(net, evolved).astype(bool)
    assert 0 < mask.sum() < len(mask)
    # every member shares the encoder (and in "readout" the LSTMs) with the others, ...
    assert (population[:, ~mask] == population[0, ~mask]).all()
    # ... while their evolved weights went separate ways
    assert len({row.tobytes() for row in population[:, mask]}) > 1
    if scope == "readout":  # workers in other processes mutate alike
        remote = tmp_path / "remote"
        argv = [*args[:-3], "--out", str(remote), "--backend", "processes", "--workers", "1",
                "--quiet"]  # fmt: skip
        assert main(argv) == 0
        with np.load(remote / "checkpoint.npz") as ckpt:
            np.testing.assert_array_equal(ckpt["population"], population)
        fitness = [json.loads((o / "history.json").read_text())["generations"][-1]["fitness"]
                   for o in (out, remote)]  # fmt: skip
        assert fitness[0] == fitness[1]


def test_evolve_scopes_are_checked():
    with pytest.raises(RunError, match=r"unknown evolve scope 'cnn'; choose from \['all', "):
        TrainConfig(pretrain_episodes=2, evolve="cnn")
    with pytest.raises(RunError, match="--evolve head keeps the warm start's encoder: give "
                                       "--pretrain or --pretrain-episodes"):  # fmt: skip
        TrainConfig(evolve="head")
    with pytest.raises(ValueError, match=r"the network has no parameters \['nope'\]"):
        mutation_mask(_tiny_net(), ("nope",))
    assert mutation_mask(_tiny_net(), None) is None
    with pytest.raises(ValueError, match="no parameter to evolve"):
        mutation_mask(_tiny_net(), ())


def test_a_missing_pretraining_dataset_is_a_clear_error(tmp_path, capsys):
    cfg = TrainConfig(preset="tiny", population=2, generations=1, episodes=1,
                      episode_seconds=2.0, pretrain=str(tmp_path / "nothing"))  # fmt: skip
    refused_as = r"--pretrain: .*nothing is not a dataset \(no manifest.json"
    with pytest.raises(RunError, match=refused_as) as refused:
        Run.create(tmp_path / "run", cfg).train(progress=False)
    assert str(refused.value).count(str(tmp_path / "nothing")) == 1  # the path, said once
    with pytest.raises(RunError, match="pretrain_epochs must be an integer >= 1, got 0"):
        TrainConfig(pretrain_epochs=0)
    assert not (tmp_path / "run").exists()  # refused before the run folder is made


def test_pretraining_data_of_another_grid_size_is_refused_before_the_run(windows_dir, tmp_path):
    small = tmp_path / "small.yaml"
    small.write_text("name: small\nroad: {type: seamless}\nsensor: {rows: 64, cols: 64}\n")
    cfg = TrainConfig(scenario=str(small), preset="tiny", population=2, generations=1,
                      episodes=1, episode_seconds=2.0, pretrain=str(windows_dir))  # fmt: skip
    with pytest.raises(RunError) as info:
        Run.create(tmp_path / "run", cfg)
    assert (
        f"--pretrain {windows_dir}: the windows have (history, grid size, horizon) = "
        "(5, 128, 5), the network needs (5, 64, 5)" in str(info.value)
    )
    assert not (tmp_path / "run").exists()


def test_the_warm_start_says_which_epoch_it_kept(windows_dir, tmp_path, capsys):
    """The line after the fit says which epoch of how many was kept, or that none beat the
    ridge fit of the read-outs alone (epoch 0: every epoch was discarded)."""
    import re

    args = ["train", "--preset", "tiny", "--population", "2", "--generations", "1",
            "--episodes", "1", "--episode-seconds", "2", "--pretrain", str(windows_dir),
            "--pretrain-epochs", "2", "--validation-episodes", "0", "--heldout", "0",
            "--out", str(tmp_path / "run")]  # fmt: skip
    assert main(args) == 0
    said = capsys.readouterr().err
    best = json.loads((tmp_path / "run" / "pretrain.json").read_text())["best_epoch"]
    kept = (
        f"epoch {best} of 2 kept"
        if best
        else "the ridge fit of the read-outs alone kept: "
        "none of the 2 epochs of gradient descent predicted the held-out tracks better"
    )
    assert re.search(r"warm start: validation MSE \S+ m\^2 on \d+ windows of held-out tracks "
                     rf"\({re.escape(kept)}; pretrain.json\)", said), said  # fmt: skip
    # the windows held out to validate are said to be (it said all were fitted)
    stats = json.loads((tmp_path / "run" / "pretrain.json").read_text())
    share = json.loads((tmp_path / "run" / "config.json").read_text())["train"][
        "pretrain_validation"
    ]
    assert (f"fitting the network to {stats['windows'] + stats['validation_windows']} windows, "
            f"less the windows of {share:.0%} of their tracks, held out to validate the fit "
            "(2 epochs at most)") in said  # fmt: skip


def test_a_run_can_record_its_own_warm_start(tmp_path, capsys):
    out = tmp_path / "run"
    args = ["train", "--preset", "tiny", "--population", "4", "--generations", "1",
            "--episodes", "1", "--episode-seconds", "3", "--pretrain-episodes", "1",
            "--pretrain-epochs", "1", "--pretrain-validation", "0", "--validation-episodes", "0",
            "--heldout", "0", "--out", str(out), "--quiet"]  # fmt: skip
    assert main(args) == 0
    stats = json.loads((out / "pretrain.json").read_text())
    seeds = Run.open(out).config.pretrain_seeds
    assert stats["recorded_episodes"] == list(seeds) and all(s % 2 == 0 for s in seeds)
    assert stats["windows"] > 0 and stats["epochs"] == 1  # (fitting: tested above)
    with pytest.raises(RunError, match="either --pretrain .* or --pretrain-episodes"):
        TrainConfig(pretrain="data", pretrain_episodes=3)
    recorded = TrainConfig(scenario="us101_3_3", preset="tiny", population=2, generations=1,
                           pretrain_episodes=2)  # fmt: skip
    with pytest.raises(RunError, match="'us101_3_3' replays a recorded scene"):
        Run.create(tmp_path / "rec", recorded).train(progress=False)
    # a resumed run refuses flags that would change its results
    assert main(["train", "--resume", str(out), "--sigma", "0.1", "--quiet"]) == 2
    assert "cannot resume with --sigma 0.1 (the run has 0.005)" in capsys.readouterr().err


def test_a_recorded_scene_run_drives_only_the_tracks_of_its_training_data(tmp_path):
    """record --split train keeps evaluate's train side; a run on that scene with it as
    warm-start data trains on exactly those tracks, and its held-out report on the others."""
    from neurotrajectory.compare.evaluation import EvalConfig, _split_dataset

    data = tmp_path / "highway-train"
    assert main(["record", "--scenario", "us101_3_3", "--split", "train", "--out", str(data),
                 "--quiet"]) == 0  # fmt: skip
    ds = load_dataset(data)
    whole = record_group("us101_3_3", 1, seed=0)
    train, test = split_by_track(whole.windows, 0.3, 0)
    assert set(ds.windows.track) == set(train.track) and ds.manifest["split"]["side"] == "train"
    out = tmp_path / "run"
    args = ["train", "--scenario", "us101_3_3", "--preset", "tiny", "--population", "2",
            "--generations", "1", "--episodes", "1", "--episode-seconds", "2", "--pretrain",
            str(data), "--pretrain-epochs", "1", "--validation-episodes", "0", "--heldout", "2",
            "--out", str(out), "--quiet"]  # fmt: skip
    assert main(args) == 0
    trained = Run.open(out).config.ego_tracks
    assert {f"USA_US101-3_3_T-1/{t}" for t in trained} == set(train.track)
    from neurotrajectory.compare.front import _other_tracks

    report = json.loads((out / "heldout.json").read_text())
    held = [t for _, t in _other_tracks("us101_3_3", trained)]  # never trained on, driven once
    assert report["ego_tracks"] == held[:2] and not set(held) & set(trained)
    assert {f"USA_US101-3_3_T-1/{t}" for t in held} >= set(test.track)
    # evaluation refuses a dataset that holds one side of a split
    (tmp_path / "data").mkdir()
    data.rename(tmp_path / "data" / "highway")
    with pytest.raises(DatasetError, match="holds only the train side"):
        _split_dataset("highway", EvalConfig(), tmp_path / "data", tmp_path, print)


class _Lagging:
    """Follows the human's set-points at 80 % of their reach: falls behind, as a network
    that has not learnt enough would."""

    action_type = "trajectory"

    def __call__(self, env, obs, info):
        return 0.8 * info["reference_setpoints"]


def _reach(w: Windows) -> np.ndarray:
    """Distance [m] from the ego to the label's last set-point, per window."""
    return np.hypot(w.target[:, -1, 0], w.target[:, -1, 1])


def test_driven_windows_are_the_visited_states_labelled_with_the_human_future():
    episodes, _ = scenario_episodes("seamless", 2, seed=5, duration=6.0)
    human = drive_windows("seamless", episodes, 5)
    recorded, _ = record_scenario("seamless", 2, seed=5, duration=6.0)
    for f in fields(Windows):  # recording is driving the reference
        np.testing.assert_array_equal(getattr(human, f.name), getattr(recorded, f.name))
    assert episodes_of(human, "seamless", 6.0) == episodes
    assert episodes_of(human, "inner_city") == []  # windows of another scenario
    visited = drive_windows("seamless", episodes, 5, _Lagging(), labels="human")
    assert list(np.unique(visited.track)) == list(np.unique(human.track))
    first = [np.flatnonzero(visited.track == t)[0] for t in np.unique(visited.track)]
    np.testing.assert_array_equal(visited.ego[first], human.take(first).ego)  # same start
    # the lagging ego is behind the human, so the human's last set-point is further ahead of
    # it than of the human at the same time of the same episode
    reach = {(t, k): d for t, k, d in zip(human.track, human.time, _reach(human), strict=True)}
    lagging = [(t, k, d) for t, k, d in zip(visited.track, visited.time, _reach(visited),
                                             strict=True) if k > 2.0]  # fmt: skip
    assert lagging and all(d > reach[(t, k)] + 0.5 for t, k, d in lagging)
    with pytest.raises(DatasetError, match="trajectory actions.*'control'"):
        from gridsim.policies import Idle

        drive_windows("seamless", episodes, 5, Idle())


def test_rejoin_labels_lead_from_the_ego_back_onto_the_human_path():
    times = 0.5 * np.arange(1, 6)
    rng = np.random.default_rng(0)
    target = (10 * rng.normal(size=(4, 5, 2))).astype(np.float32)
    on_path = rejoin_labels(target, np.zeros((4, 2)), times)
    np.testing.assert_array_equal(on_path, target)  # the ego on the human's path: unchanged
    offset = rng.normal(size=(4, 2))
    label = rejoin_labels(target, offset, times)
    assert label.dtype == target.dtype
    np.testing.assert_array_equal(label[:, -1], target[:, -1])  # same destination
    fading = np.array([0.896, 0.648, 0.352, 0.104, 0.0])  # 1 - (3 s^2 - 2 s^3), s = t / 2.5 s
    np.testing.assert_allclose(target - label, fading[None, :, None] * offset[:, None, :],
                               atol=1e-5)  # fmt: skip


def test_rejoin_labels_bring_a_lagging_ego_back_gently():
    episodes, _ = scenario_episodes("seamless", 1, seed=5, duration=6.0)
    human = drive_windows("seamless", episodes, 5, _Lagging(), labels="human")
    rejoin = drive_windows("seamless", episodes, 5, _Lagging())  # the default labels
    for f in fields(Windows):  # the same states: only the labels differ
        if f.name not in ("target", "steer", "longitudinal", "accel"):
            np.testing.assert_array_equal(getattr(human, f.name), getattr(rejoin, f.name))
    np.testing.assert_allclose(rejoin.target[:, -1], human.target[:, -1], atol=1e-5)
    behind = rejoin.time > 2.0  # the lagging ego is metres behind the human by then
    first = np.hypot(*rejoin.target[behind, 0].T), np.hypot(*human.target[behind, 0].T)
    assert behind.any() and np.all(first[0] < first[1] - 0.3)  # no leap to the human at 0.5 s
    with pytest.raises(DatasetError, match="labels must be one of"):
        drive_windows("seamless", episodes, 5, _Lagging(), labels="expert")


def test_dagger_rounds_refit_the_warm_start_on_the_states_it_visits(windows_dir, tmp_path):
    out = tmp_path / "run"
    args = ["train", "--preset", "tiny", "--population", "2", "--generations", "1",
            "--episodes", "1", "--episode-seconds", "2", "--pretrain", str(windows_dir),
            "--pretrain-epochs", "1", "--validation-episodes", "0", "--heldout", "0",
            "--dagger-rounds", "2", "--out", str(out), "--quiet"]  # fmt: skip
    assert main(args) == 0
    stats = json.loads((out / "pretrain.json").read_text())
    human = len(load_dataset(windows_dir).windows)
    rounds = stats["dagger"]
    assert len(rounds) == 2 and all(r["visited_windows"] > 0 for r in rounds)
    # every round refits on the human windows and all visited so far, less the visited
    # windows of the held-out tracks: the epoch is picked on held-out human windows only
    held_out = len(split_by_track(load_dataset(windows_dir).windows, 0.2, 0)[1])
    visited = [r["visited_windows"] for r in rounds]
    assert all(r["validation_windows"] == held_out for r in rounds)
    assert human - held_out < rounds[0]["windows"] < human - held_out + visited[0]
    assert rounds[0]["windows"] < rounds[1]["windows"] < human - held_out + sum(visited)
    assert stats["windows"] == rounds[1]["windows"] and stats["dagger_weight"] is None
    again = tmp_path / "again"
    assert main([*args[:-3], "--out", str(again), "--quiet"]) == 0
    assert json.loads((again / "pretrain.json").read_text()) == stats
    weighted = tmp_path / "weighted"
    assert main([*args[:-3], "--dagger-weight", "0.25", "--out", str(weighted), "--quiet"]) == 0
    doc = json.loads((weighted / "pretrain.json").read_text())
    assert doc["dagger_weight"] == 0.25
    assert doc["dagger"][0]["visited_windows"] == visited[0]  # the same first drive
    assert doc["dagger"][1]["validation_mse"] != rounds[1]["validation_mse"]
    assert json.loads((weighted / "config.json").read_text())["train"]["dagger_weight"] == 0.25
    with pytest.raises(RunError, match="--dagger-rounds refit the warm start"):
        TrainConfig(dagger_rounds=1)
    with pytest.raises(RunError, match="no episode of the training scenario 'inner_city'"):
        cfg = TrainConfig(scenario="inner_city", preset="tiny", population=2, generations=1,
                          pretrain=str(windows_dir), dagger_rounds=1)  # fmt: skip
        Run.create(tmp_path / "city", cfg).train(progress=False)
    assert not (tmp_path / "city").exists()  # refused before the run folder is made


def test_visited_windows_weigh_their_share_of_the_fit(windows_dir):
    w = visited_weights(30, 10, 0.25)
    assert w.mean() == pytest.approx(1.0) and w[0] == pytest.approx(w[-1] * 10 / 0.25 / 30)
    assert w[30:].sum() == pytest.approx(0.25 * w[:30].sum())
    assert visited_weights(30, 10, None) is None and visited_weights(30, 0, 0.5) is None
    human = load_dataset(windows_dir).windows
    shifted = human.take(np.arange(len(human)))
    shifted.target = shifted.target + np.float32(2.0)  # labels that pull elsewhere

    def ridge(fit, weights=None):
        net = _tiny_net()
        fit_skip(net, fit, None, weights)
        return net.skip_weight.detach().numpy().copy()

    both = Windows.concat([human, shifted])
    alike = ridge(both)
    np.testing.assert_allclose(ridge(both, np.ones(len(both))), alike, rtol=1e-5, atol=1e-6)
    nearly_none = ridge(both, visited_weights(len(human), len(shifted), 1e-9))
    np.testing.assert_allclose(nearly_none, ridge(human), rtol=1e-4, atol=1e-5)
    assert np.abs(nearly_none - alike).max() > 1e-3
    # in the whole fit: a smaller share of visited windows keeps the human windows better fitted
    net = _tiny_net()
    start = initial_genome(net, 3)
    errors = {}
    for share in (None, 0.05):
        fit = {"visited": shifted, "visited_share": share, "validation": 0.5}
        _, stats = pretrain_genome(net, start, human, 3, 0, learning_rate=1e-2, **fit)
        errors[share] = min(stats["validation_mse"])
        assert stats["validation_windows"] == len(split_by_track(human, 0.5, 0)[1])
    assert errors[0.05] < errors[None]


@pytest.mark.parametrize(
    ("weight", "message"),
    [(0, "dagger_weight must be a finite number > 0, got 0"),
     (-0.5, "dagger_weight must be a finite number > 0, got -0.5"),
     (float("nan"), "dagger_weight must be a finite number > 0, got nan"),
     ("half", "dagger_weight must be a finite number > 0, got 'half'"),
     (True, "dagger_weight must be a finite number > 0, got True")],
)  # fmt: skip
def test_the_dagger_weight_is_checked(weight, message):
    with pytest.raises(RunError, match=message):
        TrainConfig(pretrain_episodes=2, dagger_rounds=1, dagger_weight=weight)


def test_unknown_dagger_labels_are_refused():
    with pytest.raises(RunError, match=r"unknown dagger_labels 'expert'; choose from \['rejoin', "
                                       r"'human'\]"):  # fmt: skip
        TrainConfig(pretrain_episodes=2, dagger_rounds=1, dagger_labels="expert")


def test_a_dagger_weight_without_rounds_is_refused_before_the_run(tmp_path, capsys):
    with pytest.raises(RunError, match=r"--dagger-weight 0.5 weighs the DAgger rounds' windows"):
        TrainConfig(pretrain_episodes=2, dagger_weight=0.5)
    out = tmp_path / "run"
    args = ["train", "--pretrain-episodes", "2", "--dagger-rounds", "1", "--out", str(out)]
    with pytest.raises(SystemExit) as usage:  # argparse's error, before anything is made
        main([*args, "--dagger-weight", "-1"])
    assert usage.value.code == 2 and not out.exists()
    assert "argument --dagger-weight: expected a finite number > 0, got '-1'" in (
        capsys.readouterr().err
    )
    assert main([*args[:3], *args[5:], "--dagger-weight", "0.5"]) == 2
    assert "give --dagger-rounds >= 1" in capsys.readouterr().err
    assert main([*args[:3], *args[5:], "--dagger-labels", "human"]) == 2
    assert "--dagger-labels human labels the DAgger rounds' windows: give --dagger-rounds >= 1" in (
        capsys.readouterr().err
    )
    assert not out.exists()
    assert not out.exists()


def test_heldout_drives_a_finished_run_on_longer_unseen_episodes(
    windows_dir, tmp_path, capsys, monkeypatch
):
    from gridsim import outputs

    monkeypatch.setattr(outputs, "LOG_INTERVAL", 0.0)  # bars drawn at once, as on a terminal
    out = tmp_path / "run"
    args = ["train", "--preset", "tiny", "--population", "2", "--generations", "1",
            "--episodes", "1", "--episode-seconds", "2", "--pretrain", str(windows_dir),
            "--pretrain-epochs", "1", "--validation-episodes", "0", "--heldout", "0",
            "--out", str(out), "--quiet"]  # fmt: skip
    assert main(args) == 0
    report = tmp_path / "reports" / "h.json"
    cmd = ["heldout", "--run", str(out), "--episodes", "2", "--seconds", "3", "--out"]
    assert main([*cmd, str(report)]) == 0
    doc = json.loads(report.read_text())
    seeds = list(Run.open(out).config.heldout_seeds(2))
    assert doc["episode_seconds"] == 3.0 and doc["seeds"] == seeds
    assert [e["seed"] for e in doc["episodes"]] == seeds
    assert all(e["seconds"] <= 3.0 + 1e-9 for e in doc["episodes"])
    said = capsys.readouterr()
    assert "knee member on 2 held-out episodes (3 s each)" in said.out
    assert "held-out episodes: " in said.err and "/6 [" in said.err  # a bar: 3 planners x 2
    assert main([*cmd, str(report), "--overwrite", "--quiet"]) == 0
    assert "held-out episodes: " not in capsys.readouterr().err
    for seconds, said in [("nan", "expected a finite number in (0, 3600], got 'nan'"),
                          ("1e6", "expected a finite number in (0, 3600], got '1e6'")]:  # fmt: skip
        with pytest.raises(SystemExit) as exit_:  # argparse refuses the value
            main(["heldout", "--run", str(out), "--seconds", seconds, "--out", str(report)])
        assert exit_.value.code == 2 and f"--seconds: {said}" in capsys.readouterr().err


def test_an_interrupted_fit_goes_on_to_the_same_genome(windows_dir, tmp_path, monkeypatch):
    """The warm start's fit is saved after each epoch: interrupted, the same fit goes on from
    its last saved epoch to the genome and scores of an unbroken one, bit for bit; a fit of
    other inputs starts over; the file goes when the fit ends."""
    from neurotrajectory.evolve import warm_start

    w = load_dataset(windows_dir).windows
    start = initial_genome(_tiny_net(), 3)
    kwargs = {"epochs": 4, "seed": 0, "learning_rate": 1e-2, "validation": 0.3}
    whole, whole_stats = pretrain_genome(_tiny_net(), start, w, **kwargs)
    saved = tmp_path / "fit.pt"
    with monkeypatch.context() as m:  # after the second epoch is saved
        ctrl_c_at(m, warm_start, "_save_fit", 2, after=True)
        with pytest.raises(KeyboardInterrupt):
            pretrain_genome(_tiny_net(), start, w, checkpoint=saved, **kwargs)
    assert saved.is_file()
    with monkeypatch.context() as m:
        calls = _saves(m, warm_start)
        passes = ctrl_c_at(m, warm_start, "setpoint_mse", 0)  # (counts the passes)
        again, again_stats = pretrain_genome(_tiny_net(), start, w, checkpoint=saved, **kwargs)
    assert calls == [(3, 0), (4, 0)]  # epochs 1 and 2 were not fitted again
    # the held-out error after epochs 3 and 4, after the fit: the errors before the fit (on
    # the fitted windows and the held-out ones) were saved, not measured again
    assert len(passes) == 3
    np.testing.assert_array_equal(again, whole)
    assert again_stats == whole_stats
    assert not saved.exists()
    # a saved fit of other inputs (a seed, the windows' destinations) is not used
    moved = Windows(**{**{f.name: getattr(w, f.name) for f in fields(w)},
                       "destination": w.destination + 5.0})  # fmt: skip
    for other_kwargs, windows in (({**kwargs, "seed": 1}, w), (kwargs, moved)):
        with monkeypatch.context() as m:
            ctrl_c_at(m, warm_start, "_save_fit", 2, after=True)
            with pytest.raises(KeyboardInterrupt):
                pretrain_genome(_tiny_net(), start, w, checkpoint=saved, **kwargs)
        other, _ = pretrain_genome(_tiny_net(), start, windows, checkpoint=saved, **other_kwargs)
        alone, _ = pretrain_genome(_tiny_net(), start, windows, **other_kwargs)
        np.testing.assert_array_equal(other, alone)


def _saves(monkeypatch, warm_start) -> list:
    """Records ``(epochs, batch)`` of every save of the warm start's fit."""
    save, calls = warm_start._save_fit, []

    def recorded(path, key, state):
        calls.append((state.epochs, state.batch))
        save(path, key, state)

    monkeypatch.setattr(warm_start, "_save_fit", recorded)
    return calls


def test_a_fit_interrupted_inside_an_epoch_goes_on_from_its_batch(windows_dir, tmp_path,
                                                                 monkeypatch):  # fmt: skip
    """Saved within an epoch (here after every batch) and at Ctrl-C, a fit goes on from the
    batch it reached, fits no batch twice, and ends at the genome and scores of an unbroken
    fit, bit for bit."""
    from neurotrajectory.evolve import warm_start

    w = load_dataset(windows_dir).windows
    start = initial_genome(_tiny_net(), 3)
    kwargs = {"epochs": 2, "seed": 0, "learning_rate": 1e-2, "validation": 0.3, "batch_size": 2}
    whole, whole_stats = pretrain_genome(_tiny_net(), start, w, **kwargs)
    saved = tmp_path / "fit.pt"
    monkeypatch.setattr(warm_start, "SAVE_SECONDS", 0.0)
    with monkeypatch.context() as m:
        first = _saves(m, warm_start)
        ctrl_c_at(m, warm_start, "_save_fit", 3, after=True)  # the third batch's save
        with pytest.raises(KeyboardInterrupt):
            pretrain_genome(_tiny_net(), start, w, checkpoint=saved, **kwargs)
    assert first[:3] == [(0, 1), (0, 2), (0, 3)]
    batches = -(-whole_stats["windows"] // 2)
    with monkeypatch.context() as m:
        calls = _saves(m, warm_start)
        passes = ctrl_c_at(m, warm_start, "setpoint_mse", 0)
        again, again_stats = pretrain_genome(_tiny_net(), start, w, checkpoint=saved, **kwargs)
    assert calls[0] == (0, 4) and len(calls) == 2 * batches + 2 - 3  # no batch twice
    assert len(passes) == 3  # the held-out error after each epoch, the error after the fit
    np.testing.assert_array_equal(again, whole)
    assert again_stats == whole_stats
    assert not saved.exists()


def test_a_saved_fit_of_another_length_or_position_is_not_used(windows_dir, tmp_path):
    """A fit file whose position lies outside the fit asked for (more epochs than it has, a
    batch past the epoch's end) or that is damaged starts the fit over."""
    from gridsim.errors import DataWarning
    from neurotrajectory.evolve import warm_start

    w = load_dataset(windows_dir).windows
    start = initial_genome(_tiny_net(), 3)
    kwargs = {"epochs": 2, "seed": 0, "learning_rate": 1e-2, "validation": 0.3}
    whole, _ = pretrain_genome(_tiny_net(), start, w, **kwargs)
    saved = tmp_path / "fit.pt"
    for epochs, batch in ((3, 0), (0, 10**6), (2, 1), (0, 0)):
        net = _tiny_net()
        key = {"inputs": "x"}
        state = warm_start._FitState(epochs, batch, [1.0], initial_genome(net, 3), 1.0,
                                     initial_genome(net, 3), {})  # fmt: skip
        warm_start._save_fit(saved, key, state)
        size = sum(p.numel() for p in net.parameters())
        assert warm_start._read_fit(saved, key, size, 2, 100) is None, (epochs, batch)
    state.epochs, state.batch = 1, 5
    warm_start._save_fit(saved, key, state)
    assert warm_start._read_fit(saved, key, size, 2, 100).batch == 5
    assert warm_start._read_fit(saved, {"inputs": "y"}, size, 2, 100) is None
    saved.write_bytes(b"damaged")
    with pytest.warns(DataWarning, match=r"fit\.pt: the warm start's saved fit cannot be read"):
        assert warm_start._read_fit(saved, key, size, 2, 100) is None  # (hours lost: said)
    with pytest.warns(DataWarning, match="the fit starts over"):
        again, _ = pretrain_genome(_tiny_net(), start, w, checkpoint=saved, **kwargs)
    np.testing.assert_array_equal(again, whole)


def test_a_full_disk_while_the_fit_is_saved_is_an_os_error_not_a_bug(tmp_path, monkeypatch):
    """torch.save's own writer said a full disk as "RuntimeError: [enforce fail at
    inline_container.cc] unexpected pos", reported as an internal bug: the state is written
    by Python now, so the disk's errno reaches the command (which says to free space and keeps
    the work), and no half file is left."""
    import errno

    from gridsim.outputs import interrupted
    from neurotrajectory.evolve import warm_start

    class Full:
        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def write(self, data):
            raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(warm_start, "open", lambda *a, **k: Full(), raising=False)
    state = warm_start._FitState(1, 0, [1.0], np.zeros(3, np.float32), 1.0,
                                 np.zeros(3, np.float32), {})  # fmt: skip
    with pytest.raises(OSError) as err:
        warm_start._save_fit(tmp_path / "fit.pt", {"k": 1}, state)
    assert err.value.errno == errno.ENOSPC and interrupted(err.value)
    assert list(tmp_path.iterdir()) == []


def test_windows_of_other_timings_or_grids_are_refused_as_a_warm_start(windows_dir, tmp_path):
    """A dataset recorded with set-points 0.3 s apart (or a grid heading up, or of 1 m
    cells) fed a network of 0.5 s set-points without a word: its warm start's l1 was 4036
    against 88. The run names what differs; ``evaluate`` refuses a run on such scenes too."""
    import shutil

    from gridsim.scenario.loader import load_scenario
    from neurotrajectory.data.windows import recording_mismatch

    other = tmp_path / "other"
    shutil.copytree(windows_dir, other)
    manifest = json.loads((other / "manifest.json").read_text())
    manifest["setpoint_period"] = 0.3
    manifest["sensor"] = {**manifest["sensor"], "orientation": "heading_up"}
    (other / "manifest.json").write_text(json.dumps(manifest))
    config = TrainConfig(preset="tiny", population=4, generations=1, episodes=1,
                         episode_seconds=3.0, pretrain=str(other))  # fmt: skip
    with pytest.raises(
        RunError,
        match=r"--pretrain .*: its windows were recorded with "
        r"env.setpoint_period 0.3 \(the run's 0.5\), "
        r"sensor.orientation 'heading_up' \(the run's 'north_up'\)",
    ):
        Run.create(tmp_path / "run", config)
    assert not (tmp_path / "run").exists()
    seamless = load_scenario("seamless").config
    assert recording_mismatch(json.loads((windows_dir / "manifest.json").read_text()),
                              seamless) is None  # fmt: skip
    assert "sensor.cell_size 1.0" in recording_mismatch({"sensor": {"cell_size": 1.0}}, seamless)
