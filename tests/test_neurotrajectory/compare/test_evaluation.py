"""Labelled windows (recording, storage, splits) and the evaluation command end to end."""

import csv
import json
import re
import shutil

import numpy as np
import pytest

from neurotrajectory.cli import main
from neurotrajectory.data.commands import implied_commands
from neurotrajectory.data.storage import load_dataset, save_dataset
from neurotrajectory.data.windows import DatasetError, record_group, split_by_track
from neurotrajectory.evolve.runs import Run, TrainConfig

#: Training runs, rollouts or subprocesses: left out of the quick loop (`pytest -m "not slow"`).
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("nt") / "run"
    cfg = TrainConfig(preset="tiny", population=4, generations=1, episodes=1,
                      episode_seconds=3.0, seed=2)  # fmt: skip
    Run.create(out, cfg).train(progress=False)
    return out


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """Datasets of a seamless and the urban group, recorded through the command line."""
    root = tmp_path_factory.mktemp("data")
    for group, extra in (("seamless", ["--episodes", "2", "--episode-seconds", "6"]),
                         ("urban", [])):  # fmt: skip
        assert main(["record", "--scenario", group, "--out", str(root / group), "--quiet",
                     *extra]) == 0  # fmt: skip
    return root


def test_recorded_windows_are_labelled_consistently(data):
    ds = load_dataset(data / "urban")
    w = ds.windows
    assert ds.manifest["source"] == "human (NGSIM)" and ds.manifest["group"] == "urban"
    n = len(w)
    assert w.grids.shape == (n, 5, 128, 128) and w.grids.dtype == np.uint8
    assert w.target.shape == (n, 5, 2) and np.all(np.isfinite(w.target))
    # every recorded track of both urban scenes drove as the ego
    scenes = {t.split("/")[0] for t in w.track}
    assert scenes == {"USA_Lanker-1_1_T-1", "USA_Peach-4_8_T-1"}
    assert len(set(w.track)) >= 25
    steer, lon, _ = implied_commands(w.target, w.speed, w.heading, ds.times)
    np.testing.assert_array_equal(steer, w.steer)
    np.testing.assert_array_equal(lon, w.longitudinal)
    # the label starts where the ego is heading: the first set-point lies ahead, not behind
    first = w.target[:, 0]
    ahead = first[:, 0] * w.ego[:, 4] + first[:, 1] * w.ego[:, 5]
    assert np.mean(ahead > -0.1) > 0.99


def test_recording_is_deterministic_and_round_trips(tmp_path):
    a = record_group("seamless", 1, seed=4, duration=4.0)
    b = record_group("seamless", 1, seed=4, duration=4.0)
    c = record_group("seamless", 1, seed=5, duration=4.0)
    np.testing.assert_array_equal(a.windows.grids, b.windows.grids)
    np.testing.assert_array_equal(a.windows.target, b.windows.target)
    assert not np.array_equal(a.windows.target, c.windows.target)
    save_dataset(a, tmp_path / "d")
    back = load_dataset(tmp_path / "d")
    for name in ("grids", "ego", "destination", "target", "steer", "track", "time"):
        np.testing.assert_array_equal(getattr(back.windows, name), getattr(a.windows, name))
    assert (
        back.manifest["scenarios"][0]["episode_seeds"]
        == a.manifest["scenarios"][0]["episode_seeds"]
    )


def test_damaged_datasets_give_clear_errors(tmp_path):
    ds = record_group("seamless", 1, seed=1, duration=3.0)
    save_dataset(ds, tmp_path / "d")
    with pytest.raises(DatasetError, match="not empty"):
        save_dataset(ds, tmp_path / "d")
    shard = tmp_path / "d" / "shard-00000.npz"
    shard.write_bytes(shard.read_bytes()[:-10])
    with pytest.raises(DatasetError, match="checksum mismatch"):
        load_dataset(tmp_path / "d")
    shard.unlink()
    with pytest.raises(DatasetError, match="shard-00000.npz is missing"):
        load_dataset(tmp_path / "d")
    with pytest.raises(DatasetError, match="no manifest.json"):
        load_dataset(tmp_path / "nothing")
    manifest = tmp_path / "d" / "manifest.json"
    doc = json.loads(manifest.read_text())
    cases = (([], "'shards' must be a non-empty list, got []"),
             ([{"windows": 3}], "shards[0] must be an object with the strings 'file' and "
                                "'sha256', got {'windows': 3}"),
             ([{"file": 5, "sha256": "x"}], "shards[0] must be an object"))  # fmt: skip
    for shards, message in cases:
        manifest.write_text(json.dumps({**doc, "shards": shards}))
        with pytest.raises(DatasetError, match=re.escape(f"{manifest}: {message}")):
            load_dataset(tmp_path / "d")


def test_splits_never_share_a_track(data):
    w = load_dataset(data / "urban").windows
    train, test = split_by_track(w, 0.3, seed=0)
    assert len(train) + len(test) == len(w)
    assert not set(train.track) & set(test.track)
    assert 0.15 < len(set(test.track)) / len(set(w.track)) < 0.45
    again, _ = split_by_track(w, 0.3, seed=0)
    np.testing.assert_array_equal(again.track, train.track)
    with pytest.raises(DatasetError, match=">= 2 tracks"):
        split_by_track(w.take(np.flatnonzero(w.track == w.track[0])))


def _table(path):
    with open(path) as fh:
        return list(csv.DictReader(fh))


def test_evaluate_runs_end_to_end_on_a_tiny_configuration(tiny_run, data, tmp_path, capsys):
    out = tmp_path / "eval"
    args = ["evaluate", "--run", str(tiny_run), "--data", str(data), "--out", str(out),
            "--groups", "seamless", "urban", "--e2e-epochs", "1", "--closed-loop-episodes", "1",
            "--closed-loop-seconds", "2", "--videos", "--quiet"]  # fmt: skip
    assert main(args) == 0
    assert "closed loop" not in capsys.readouterr().err  # --quiet: no progress bars
    assert main([*args[:-1], "--out", str(tmp_path / "loud")]) == 0
    said = capsys.readouterr().err  # where everything went
    assert f"neurotrajectory: wrote {tmp_path / 'loud'}: closed_loop.csv, eval_config.json" in said
    assert f"videos in {tmp_path / 'loud' / 'videos'}" in said
    import imageio.v3 as iio

    videos = sorted(p.name for p in (out / "videos").iterdir())
    assert len(videos) == 6 * 3  # 6 policies x (1 seamless + 2 urban scenes)
    assert len(iio.imread(out / "videos" / "seamless-seamless-dwa.mp4")) == 21  # 2 s + first
    for name in ("table2.md", "table2.csv", "closed_loop.csv", "results.json",
                 "fig8_rmse_per_setpoint.png", "fig9_window_rmse.png", "eval_config.json",
                 "models/end2end-urban/end2end.pt"):  # fmt: skip
        assert (out / name).stat().st_size > 0, name
    # the windows are the datasets': no recording settings of evaluate's own are claimed
    settings = json.loads((out / "eval_config.json").read_text())
    assert settings["data"] == str(data) and settings["episodes"] is None
    assert settings["episode_seconds"] is None
    rows = _table(out / "table2.csv")
    methods = {r["method"] for r in rows}
    assert {
        "constant velocity",
        "destination curve",
        "DWA",
        "End2End",
        "NeuroTrajectory",
    } <= methods
    assert {r["group"] for r in rows} == {"seamless", "urban"}
    assert {r["source"] for r in rows if r["group"] == "urban"} == {"human (NGSIM)"}
    # a run on the generated road trained on no track of the urban scenes
    groups = json.loads((out / "results.json").read_text())["groups"]
    assert [g["trained_test_tracks"] for g in groups] == [[], []]
    assert "Not held out" not in (out / "table2.md").read_text()
    for r in rows:
        assert float(r["max_ex"]) >= float(r["mean_ex"]) >= 0
        assert float(r["rmse"]) > 0
    # the constant-velocity row is reproducible from the held-out windows
    from neurotrajectory.compare.baselines.constant_velocity import constant_velocity_setpoints
    from neurotrajectory.compare.metrics import accuracy

    ds = load_dataset(data / "urban")
    _, test = split_by_track(ds.windows, 0.3, seed=0)
    cv = accuracy(constant_velocity_setpoints(test.speed, test.heading, ds.times), test.target,
                  test.heading)  # fmt: skip
    row = next(r for r in rows if r["group"] == "urban" and r["method"] == "constant velocity")
    assert float(row["rmse"]) == pytest.approx(cv.rmse, abs=1e-4)
    assert int(row["windows"]) == len(test)
    loop = _table(out / "closed_loop.csv")
    human = next(r for r in loop if r["group"] == "seamless" and r["method"] == "human reference")
    assert float(human["completed"]) == 1.0 and float(human["l1"]) < 1e-6
    assert float(human["progress"]) == pytest.approx(1.0, abs=0.03)
    md = (out / "table2.md").read_text()
    assert "| RMSE |" in md and "human (NGSIM)" in md and "simulator" in md
    doc = json.loads((out / "results.json").read_text())
    assert doc["neurotrajectory"]["urban"]["population"] == 4
    # every closed-loop episode is listed, and the table's figures are their means
    urban = next(g for g in doc["groups"] if g["group"] == "urban")
    for method, stats in urban["closed_loop"].items():
        episodes = stats["per_episode"]
        assert len(episodes) == stats["episodes"] == 2, method  # 1 seed x 2 urban scenes
        assert len({e["scenario"] for e in episodes}) == 2
        assert stats["completed"] == pytest.approx(np.mean([e["completed"] for e in episodes]))
        assert all(isinstance(e["seed"], int) for e in episodes)
    # on recorded scenes the closed loop drives tracks of the test side, the first of each
    # scene (a random ego drove mostly the tracks End2End and the run were trained on)
    test_tracks = set(split_by_track(ds.windows, 0.3, seed=0)[1].track.tolist())
    driven = {f"{e['scenario']}/{e['track']}" for e in urban["closed_loop"]["DWA"]["per_episode"]}
    scenes = {"lankershim_1_1": "USA_Lanker-1_1_T-1", "peachtree_4_8": "USA_Peach-4_8_T-1"}
    assert {f"{scenes[n.split('/')[0]]}/{n.split('/')[1]}" for n in driven} <= test_tracks


def test_evaluation_is_deterministic(tiny_run, tmp_path):
    tables = []
    for name in ("a", "b"):
        args = ["evaluate", "--run", str(tiny_run), "--out", str(tmp_path / name), "--groups",
                "seamless", "--episodes", "2", "--episode-seconds", "4", "--e2e-epochs", "1",
                "--closed-loop-episodes", "0", "--quiet"]  # fmt: skip
        assert main(args) == 0
        tables.append((tmp_path / name / "table2.csv").read_text())
    assert tables[0] == tables[1]
    assert (tmp_path / "a" / "data" / "seamless" / "manifest.json").is_file()


def test_an_interrupted_evaluation_goes_on_with_the_windows_it_recorded(
    tiny_run, tmp_path, monkeypatch, capsys
):
    """Ctrl-C after a group's windows are recorded keeps them; the same command goes on with
    them (records nothing again) to the tables of an unbroken evaluation; other settings are
    refused while the interrupted one is kept."""
    from breaks import ctrl_c_at

    from neurotrajectory.compare import evaluation

    args = ["evaluate", "--run", str(tiny_run), "--groups", "seamless", "--episodes", "2",
            "--episode-seconds", "4", "--e2e-epochs", "1", "--closed-loop-episodes", "0",
            "--quiet"]  # fmt: skip
    assert main([*args, "--out", str(tmp_path / "whole")]) == 0
    out, partial = tmp_path / "eval", tmp_path / ".eval.partial"
    with monkeypatch.context() as m:  # after the windows, before End2End is trained
        ctrl_c_at(m, evaluation, "_evaluate_group", 1)
        assert main([*args, "--out", str(out)]) == 130
    assert f"the windows recorded so far are kept in {partial}" in capsys.readouterr().err
    assert (partial / "data" / "seamless" / "manifest.json").is_file() and not out.exists()
    other = [*args]
    other[other.index("--episode-seconds") + 1] = "5"
    assert main([*other, "--out", str(out)]) == 2  # the windows would change: refused
    assert ("holds the windows of an interrupted evaluation recorded with other "
            "--episode-seconds: give the values") in capsys.readouterr().err  # fmt: skip
    with monkeypatch.context() as m:  # End2End and the closed loop changed: go on
        recorded = ctrl_c_at(m, evaluation, "record_dataset", 0)  # (counts the recordings)
        assert main([*args, "--out", str(out), "--closed-loop-episodes", "1"]) == 0
    assert recorded == [] and not partial.exists()
    config = json.loads((out / "eval_config.json").read_text())
    assert config["closed_loop_episodes"] == 1  # the settings it went on with
    same = [(d / "table2.csv").read_text() for d in (tmp_path / "whole", out)]
    assert same[0] == same[1]  # (the same windows, the same open-loop table)


def test_an_evaluation_interrupted_while_recording_goes_on_or_records_again(
    tiny_run, tmp_path, monkeypatch, capsys
):
    """Ctrl-C while a group's windows are recorded keeps record's checkpoint; the same command
    goes on from it, and a group whose scenario file changed meanwhile is recorded again
    (record alone would refuse it: its arguments are the same)."""
    from breaks import ctrl_c_at

    from neurotrajectory.data import recording, windows

    monkeypatch.setattr(recording, "CHECKPOINT_SECONDS", 0.0)
    mine = tmp_path / "mine.yaml"
    mine.write_text("name: mine\nroad: {type: seamless}\n")
    args = ["evaluate", "--run", str(tiny_run), "--group", f"mine={mine}", "--episodes", "3",
            "--episode-seconds", "4", "--e2e-epochs", "1",
            "--closed-loop-episodes", "0"]  # fmt: skip
    out = tmp_path / "eval"
    for edit in (False, True):
        with monkeypatch.context() as m:
            ctrl_c_at(m, windows, "_episode_windows", 2)  # inside the second episode
            assert main([*args, "--quiet", "--out", str(out)]) == 130
        assert (tmp_path / ".eval.partial" / "data" / "mine" / "progress.json").is_file()
        if edit:
            mine.write_text("name: mine\nroad: {type: seamless, lanes: 2}\n")
        assert main([*args, "--out", str(out)]) == 0
        said = capsys.readouterr().err
        assert ("mine: recording again: " in said) == edit, said
        assert ("going on with the interrupted recording" in said) != edit
        shutil.rmtree(out)


def test_bad_input_gives_clear_errors(tiny_run, tmp_path, capsys):
    assert main(["evaluate", "--run", str(tmp_path), "--out", str(tmp_path / "e")]) == 2
    assert "not a run directory" in capsys.readouterr().err
    assert not (tmp_path / "e").exists()
    assert main(["record", "--scenario", "nowhere", "--out", str(tmp_path / "r")]) == 2
    assert "unknown scenario 'nowhere'" in capsys.readouterr().err
    assert main(["evaluate", "--run", str(tiny_run), "--data", str(tmp_path / "none"),
                 "--out", str(tmp_path / "e2"), "--groups", "urban"]) == 2  # fmt: skip
    said = capsys.readouterr().err
    assert f"--data {tmp_path / 'none'}: no dataset of the group urban" in said
    hint = "neurotrajectory record --scenario urban --episodes 8 --episode-seconds 30 --seed 0"
    assert f"{hint} --out" in said and "--groups" in said
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("mine")
    assert main(["evaluate", "--run", str(tiny_run), "--out", str(tmp_path / "full")]) == 2
    assert "not empty" in capsys.readouterr().err
    assert (tmp_path / "full" / "keep.txt").read_text() == "mine"
    for command in ("record", "evaluate"):  # refused before any recording
        args = ["--scenario", "seamless"] if command == "record" else ["--run", str(tiny_run)]
        assert main([command, *args, "--out", str(tmp_path / "full" / "keep.txt")]) == 2
        assert "keep.txt: is a file, expected a folder" in capsys.readouterr().err
        assert main([command, *args, "--out", str(tmp_path / "full"), "--quiet"]) == 2
        assert "full: exists and is not empty: choose another --out" in (capsys.readouterr().err)


def test_progress_is_left_out_when_the_human_did_not_move():
    from neurotrajectory.compare.closed_loop import MIN_HUMAN_PATH, _progress, summarise

    assert _progress(12.0, 10.0) == pytest.approx(1.2)
    assert np.isnan(_progress(12.0, 0.5 * MIN_HUMAN_PATH))  # a car waiting at a light
    rows = [{"seed": 1, "progress": 1.2, "completed": 1.0},
            {"seed": 2, "progress": float("nan"), "completed": 0.0}]  # fmt: skip
    out = summarise(rows)
    assert out["progress"] == pytest.approx(1.2) and out["completed"] == 0.5
    assert out["episodes"] == 2


class StandStill:
    """A toy baseline: every set-point where the ego is now."""

    name = "stand still"

    def __init__(self, setting) -> None:
        self.setting = setting

    def predict(self, batch) -> np.ndarray:
        return np.zeros((len(batch), len(self.setting.times), 2))


def test_a_registered_baseline_is_scored_open_and_closed_loop(tiny_run, data, tmp_path,
                                                               monkeypatch):  # fmt: skip
    """A planner class appended to ``methods.PLANNERS`` gets its rows in Table II and the
    closed loop, under its ``name``."""
    from neurotrajectory.compare import methods
    from neurotrajectory.compare.metrics import accuracy

    monkeypatch.setattr(methods, "PLANNERS", [*methods.PLANNERS, StandStill])
    out = tmp_path / "eval"
    assert main(["evaluate", "--run", str(tiny_run), "--data", str(data), "--out", str(out),
                 "--groups", "seamless", "--e2e-epochs", "1", "--closed-loop-episodes", "1",
                 "--closed-loop-seconds", "3", "--quiet"]) == 0  # fmt: skip
    (row,) = [r for r in _table(out / "table2.csv") if r["method"] == StandStill.name]
    _, test = split_by_track(load_dataset(data / "seamless").windows, 0.3, seed=0)
    still = accuracy(np.zeros_like(test.target), test.target, test.heading)
    assert float(row["rmse"]) == pytest.approx(still.rmse, abs=1e-4) and still.rmse > 1.0
    (loop,) = [r for r in _table(out / "closed_loop.csv") if r["method"] == StandStill.name]
    assert float(loop["progress"]) < 0.5  # it brakes to a stop


def test_a_group_whose_test_tracks_were_trained_on_says_so():
    from neurotrajectory.compare.report import not_held_out

    assert not_held_out("mine", ["S/1"], 4) == (
        "mine: 1 of its 4 test tracks was a training track of the NeuroTrajectory run (S/1): "
        "its figures on this group are not held-out ones"
    )
    many = not_held_out("mine", [f"S/{k}" for k in range(1, 6)], 9)
    assert (
        "5 of its 9 test tracks were training tracks of the NeuroTrajectory run (S/1, S/2, "
        "S/3, ...)" in many
    )


def test_closed_loop_figures_read_in_one_style():
    """Markdown's closed-loop cells: three significant digits, thousands written out, float
    noise at zero as 0.000 (not 1.04e-10, 2.54e+05, 3e-08 side by side)."""
    from neurotrajectory.compare.report import _number

    cells = [8.58e-11, -3e-8, 0.0448, 0.9, 1.0, 6.69, 844.4, 1284.6, 225894.2]
    assert [_number(v) for v in cells] == ["0.000", "0.000", "0.0448", "0.9", "1", "6.69",
                                           "844", "1,285", "225,894"]  # fmt: skip
    # shares and speeds: fixed decimals per column (1 beside 0.333, 8 beside 7.22 before)
    from neurotrajectory.compare.report import _loop_cell

    assert [_loop_cell("completed", v) for v in (1.0, 1 / 3, 0.0, -1e-12)] == [
        "1.00", "0.33", "0.00", "0.00"]  # fmt: skip
    assert [_loop_cell("mean_speed", v) for v in (8.0, 7.2233)] == ["8.00", "7.22"]
    assert _loop_cell("mean_steer_rate", 0.00722) == "0.0072" and _loop_cell("episodes", 3.0) == "3"


def test_the_mean_steering_rate_is_the_rate_applied():
    """A policy that steers at 0.05 rad/s every tick has a mean steering rate of 0.05 rad/s
    (l2 sums the rate over the ticks; it was once divided by the tick length again)."""
    from neurotrajectory.compare.closed_loop import drive_episodes

    class Steer:
        action_type = "control"

        def __call__(self, env, obs, info):
            return np.array([0.0, 0.05], np.float32)

    row = drive_episodes("seamless", Steer(), [3], 2.0)[0]
    assert row["seconds"] == pytest.approx(2.0)
    assert row["mean_steer_rate"] == pytest.approx(0.05, rel=1e-6)
    assert row["l2"] == pytest.approx(0.05 * 20, rel=1e-6)  # 20 ticks of 0.1 s


def test_a_dataset_of_other_files_is_not_evaluated_as_the_group(tiny_run, data, tmp_path,
                                                                capsys):  # fmt: skip
    """``--data`` holds a dataset per group: one recorded from other scenarios, or from
    files changed since, is refused, naming them (its windows were scored as the group's,
    while the closed loop drove the group's own files)."""
    import shutil

    other = tmp_path / "other"
    shutil.copytree(data / "urban", other / "seamless")  # urban's windows named seamless
    args = ["--run", str(tiny_run), "--e2e-epochs", "1", "--closed-loop-episodes", "1", "--quiet"]
    assert main(["evaluate", *args, "--data", str(other), "--groups", "seamless",
                 "--out", str(tmp_path / "e1")]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert "recorded from lankershim_1_1, peachtree_4_8, not from the files of the group " \
        "seamless (seamless)" in err  # fmt: skip
    mine = tmp_path / "mine.yaml"
    mine.write_text("name: mine\nroad: {type: seamless}\n")
    assert main(["record", "--scenario", str(mine), "--name", "mine", "--episodes", "2",
                 "--episode-seconds", "4", "--out", str(tmp_path / "d" / "mine"),
                 "--quiet"]) == 0  # fmt: skip
    mine.write_text("name: mine\nroad: {type: seamless, lanes: 2}\n")
    assert main(["evaluate", *args, "--data", str(tmp_path / "d"), "--group", f"mine={mine}",
                 "--out", str(tmp_path / "e2")]) == 2  # fmt: skip
    assert f"recorded from files that have changed since (changed: {mine})" in \
        capsys.readouterr().err  # fmt: skip
    assert not (tmp_path / "e1").exists() and not (tmp_path / "e2").exists()


def test_an_evaluation_video_names_its_scene():
    """A group of several scenes says which one a video drives (it said the group only)."""
    from neurotrajectory.compare.evaluation import _video_label

    assert _video_label("End2End", "urban", "lankershim_1_1") == "End2End, urban (lankershim_1_1)"
    assert _video_label("DWA", "seamless", "seamless") == "DWA, seamless"
    assert _video_label("DWA", "mine", "my/scenes/a.yaml") == "DWA, mine (a)"


def test_an_evaluation_video_names_its_seed_and_track(tmp_path, monkeypatch):
    """The video's caption names the seed (and on a recorded scene the track) that drives its
    episode again (it named the method and group only; the seed was in results.json)."""
    from neurotrajectory.compare import closed_loop

    labels = []
    real = closed_loop.record_episode

    def spy(env, policy, video, seed=None, label=None, **kw):
        labels.append((video is not None, label))
        return real(env, policy, None, seed=seed, label=label, **kw)

    monkeypatch.setattr(closed_loop, "record_episode", spy)
    from gridsim.policies import Reference

    closed_loop.closed_loop("seamless", Reference(), [5, 6], 1.0, tmp_path / "v.mp4",
                            label="DWA, seamless")  # fmt: skip
    assert labels == [(True, "DWA, seamless, seed 5"), (False, "DWA, seamless, seed 6")]
    labels.clear()
    closed_loop.closed_loop("us101_4_1", Reference(), [5], 1.0, tmp_path / "w.mp4",
                            label="DWA, highway", tracks=["395"])  # fmt: skip
    assert labels == [(True, "DWA, highway, track 395, seed 5")]


def test_a_group_too_small_to_split_says_which_and_how(tmp_path):
    """``--episodes 1`` gave "need windows from >= 2 tracks to split, got 1" alone."""
    from neurotrajectory.compare import evaluation
    from neurotrajectory.data.recording import record_dataset
    from neurotrajectory.data.windows import DatasetError

    record_dataset(tmp_path / "one", "seamless", 1, duration=3.0)
    with pytest.raises(
        DatasetError,
        match=r"seamless: need windows from >= 2 tracks to split, "
        r"got 1: .*record more of the group \(--episodes\)",
    ):
        evaluation._split(tmp_path / "one", "seamless", evaluation.EvalConfig())


def test_going_on_with_data_is_not_refused_for_windows_it_does_not_read(tmp_path):
    """An interrupted evaluation that recorded windows, run again with --data: the windows
    kept are not read (the datasets are), so nothing is refused (it named --episodes and
    --episode-seconds, which the user had not changed)."""
    from neurotrajectory.compare.evaluation import _go_on_or_start

    partial = tmp_path / ".eval.partial"
    (partial / "data" / "seamless").mkdir(parents=True)
    then = {"episodes": 8, "episode_seconds": 30.0, "seed": 0, "data": None}
    (partial / "eval_config.json").write_text(json.dumps(then))
    said = []
    _go_on_or_start(partial, {**then, "episodes": None, "episode_seconds": None,
                              "data": str(tmp_path / "sets")}, said.append)  # fmt: skip
    assert "going on with the interrupted evaluation" in said[0] and "--data" in said[0]


def test_fig9_shows_each_methods_worst_window():
    """The box plot's whiskers hid the worst windows ("farther windows not drawn": urban's
    max e_x of 4.09 m went unseen): each method's worst is a red x, or a red triangle with
    its value where it lies above the panel."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from neurotrajectory.compare.report import _worst_windows

    rng = np.random.default_rng(0)
    errors = [rng.uniform(0.2, 1.0, 200), np.r_[rng.uniform(0.2, 1.0, 200), 9.5]]
    fig, ax = plt.subplots()
    _worst_windows(ax, errors, ax.boxplot(errors, showfliers=False))
    marks = [(line.get_marker(), *line.get_xydata()[0]) for line in ax.lines
             if line.get_marker() in ("x", "^")]  # fmt: skip
    assert marks[0] == ("x", 1.0, pytest.approx(errors[0].max()))
    assert marks[1][:2] == ("^", 2.0) and marks[1][2] <= ax.get_ylim()[1]
    assert [t.get_text() for t in ax.texts] == ["9.5"]
    plt.close(fig)


def test_a_group_of_other_timings_is_refused_before_any_group_is_recorded(
    tiny_run, data, tmp_path, capsys, monkeypatch
):
    """A run of 0.5 s set-points evaluated on a group of 0.3 s ones was refused only once
    that group's windows were recorded, after the groups before it had been recorded and
    scored (minutes each): every group is checked first, its scenarios or its ``--data``
    dataset, and nothing is recorded, trained or written."""
    from neurotrajectory.compare import evaluation

    def never(*args, **kwargs):
        raise AssertionError("recorded before the groups were checked")

    monkeypatch.setattr(evaluation, "record_dataset", never)
    other = tmp_path / "other.yaml"
    other.write_text("name: other\nroad: {type: seamless}\nenv: {setpoint_period: 0.3}\n")
    args = ["evaluate", "--run", str(tiny_run), "--quiet", "--groups", "seamless",
            "--group", f"other={other}"]  # fmt: skip
    assert main([*args, "--out", str(tmp_path / "e1")]) == 2
    err = capsys.readouterr().err
    assert f"other: the run {tiny_run} does not fit the group's scenarios: its windows " \
        "were recorded with env.setpoint_period 0.3 (the run's 0.5)" in err  # fmt: skip
    assert "evaluate it on a scenario of the run's settings" in err
    # with --data: the dataset's manifest says it, before the first group is scored
    given = tmp_path / "given"
    shutil.copytree(data / "seamless", given / "seamless")
    manifest = json.loads((given / "seamless" / "manifest.json").read_text())
    manifest["sensor"]["cell_size"] = 1.0
    (given / "seamless" / "manifest.json").write_text(json.dumps(manifest))
    monkeypatch.setattr(evaluation, "_evaluate_group", never)
    assert main(["evaluate", "--run", str(tiny_run), "--quiet", "--groups", "seamless",
                 "--data", str(given), "--out", str(tmp_path / "e2")]) == 2  # fmt: skip
    assert "sensor.cell_size 1.0 (the run's 0.5)" in capsys.readouterr().err
    assert not (tmp_path / "e1").exists() and not (tmp_path / "e2").exists()
