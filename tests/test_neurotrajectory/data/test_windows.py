"""Recording windows on recorded scenes: memory that does not grow with the tracks, and one
warning for the tracks a random ego is not drawn from."""

import gc
import hashlib
import json
import math
import re
import warnings
import weakref
from dataclasses import fields
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from breaks import ctrl_c_at

from gridsim.errors import DataWarning, ScenarioError
from gridsim.outputs import write_npz
from gridsim.scenario.families.recorded import recorded_scene
from gridsim.scenario.loader import load_scenario
from neurotrajectory.data import recording, storage, windows
from neurotrajectory.data.windows import drive_windows, scenario_episodes


def test_one_environment_at_a_time_while_recording_a_scene_track_by_track(monkeypatch):
    """Each ego track is its own environment, holding the whole scene's traffic: the one
    before is let go when the next is built (all were kept, memory grew with the tracks
    squared: 18 GB for 1,000 vehicles)."""
    made: list[weakref.ref] = []
    alive_at_build: list[int] = []

    class Counted(windows.GridSimEnv):
        def __init__(self, *args, **kwargs):
            gc.collect()
            alive_at_build.append(sum(r() is not None for r in made))
            super().__init__(*args, **kwargs)
            made.append(weakref.ref(self))

    monkeypatch.setattr(windows, "GridSimEnv", Counted)
    planned, _ = scenario_episodes("us101_3_3")
    found = drive_windows("us101_3_3", planned[:4], stride=10)
    assert len(made) == 4 and alive_at_build == [0, 0, 0, 0]
    assert len(set(found.track.tolist())) == 4


def test_tracks_a_random_ego_is_not_drawn_from_are_named_once():
    """``record`` drives every track that lasts the horizon, trucks too: one warning names
    them all (each environment warned of its own, one line per track)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        planned, _ = scenario_episodes("us101_3_3")
        mine = [p for p in planned if p.track.rsplit("/", 1)[1] in ("387", "401", "388")]
        drive_windows("us101_3_3", mine, stride=10)
    said = [str(w.message) for w in caught if issubclass(w.category, DataWarning)]
    assert len(said) == 1, said
    assert (
        "2 of the 12 tracks driven as the ego are not ones a random ego is drawn from (2 "
        "of a vehicle longer than 6 m): 387, 401;" in said[0]
    )  # why, not "validate names why"


def test_tracks_faster_than_the_ego_may_drive_are_not_recorded_nor_drawn(tmp_path, capsys):
    """A human faster than ``ego.vehicle.v_max`` outruns the ego that drives its track: its
    windows were labelled from where the ego fell behind (a probe's scene at 31 m/s against
    the default 25: the last set-point 98 m ahead instead of 78) and ``l1`` of the human's
    own drive was 255,948. Such tracks are neither recorded nor drawn as a random ego, and
    the key to raise is named."""
    from gridsim.errors import DataError
    from gridsim.scenario.families.recorded import ego_candidates, outruns_ego

    path = tmp_path / "slow.yaml"
    head = "name: slow\nroad: {type: recorded, map: builtin:USA_US101-4_1_T-1}\n"
    path.write_text(head + "ego: {vehicle: {v_max: 15.0}}\n")
    slow, usual = load_scenario(str(path)), load_scenario("us101_4_1")
    tracks = recorded_scene(usual)[1]
    fast = {t.track_id for t in tracks if t.speed.max() > 15.0}
    assert fast and {t.track_id for t in tracks if outruns_ego(slow, t)} == fast
    assert not any(outruns_ego(usual, t) for t in tracks)  # the shipped scenes: none (19 m/s)
    assert not fast & {t.track_id for t in ego_candidates(slow)}
    assert fast & {t.track_id for t in ego_candidates(usual)}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        planned, _ = scenario_episodes(str(path))
    recorded = {p.track.rsplit("/", 1)[1] for p in planned}
    assert recorded and not recorded & fast
    said = [str(w.message) for w in caught if "faster than ego.vehicle.v_max 15 m/s" in
            str(w.message)]  # fmt: skip
    top = max(float(t.speed.max()) for t in tracks)
    assert len(said) == 1 and f"set ego.vehicle.v_max >= {math.ceil(10 * top) / 10:.1f}" in said[0]
    path.write_text(head + "ego: {vehicle: {v_max: 3.0}}\n")  # no track is slow enough
    with pytest.raises(DataError, match="faster than ego.vehicle.v_max 3 m/s \\(raise it"):
        gym.make("GridSim-v0", scenario=str(path)).reset(seed=0)


def test_a_scenario_that_names_its_ego_tracks_records_only_them(tmp_path):
    """``record`` of a recorded scene whose YAML lists ``ego.track`` drives those tracks (it
    drove every track of the scene, without a word); one id alone is one episode."""
    path = tmp_path / "mine.yaml"
    head = "name: mine\nroad: {type: recorded, map: builtin:USA_US101-3_3_T-1}\n"
    path.write_text(head + 'ego: {track: ["363", "376", "388"]}\n')
    planned, about = scenario_episodes(str(path))
    assert [p.track.rsplit("/", 1)[1] for p in planned] == ["363", "376", "388"]
    assert about["tracks"] == 3
    path.write_text(head + "ego: {track: 399}\n")
    assert [p.track for p in scenario_episodes(str(path))[0]] == ["USA_US101-3_3_T-1/399"]
    assert len(scenario_episodes("us101_3_3")[0]) == 12  # (ego.track: random) every track
    # an id not in the scene is refused (it gave 0 episodes and "no windows were recorded")
    path.write_text(head + 'ego: {track: ["363", "99999"]}\n')
    with pytest.raises(ScenarioError, match=r"lists 1 track\(s\) not in scene .*: 99999"):
        scenario_episodes(str(path))


def _windows(n: int, first: int = 0, track: str = "s/1") -> windows.Windows:
    """``n`` made-up windows, told apart by their values (``first`` on)."""
    rng = np.random.default_rng(first)
    return windows.Windows(
        grids=rng.integers(0, 255, (n, 2, 8, 8), dtype=np.uint8),
        ego=np.arange(first, first + n, dtype=np.float32)[:, None].repeat(6, axis=1),
        destination=np.zeros((n, 2), np.float32),
        target=np.zeros((n, 5, 2), np.float32),
        steer=np.zeros(n, np.int64),
        longitudinal=np.zeros(n, np.int64),
        accel=np.zeros(n, np.float32),
        vehicle=np.ones((n, 3), np.float32),
        track=np.array([track] * n),
        time=np.zeros(n, np.float32),
    )


def _shard_digests(folder: Path) -> list[tuple[str, int, str]]:
    manifest = json.loads((folder / "manifest.json").read_text())
    return [(s["file"], s["windows"], s["sha256"]) for s in manifest["shards"]]


def test_windows_written_as_they_come_make_the_shards_of_the_whole(tmp_path, monkeypatch):
    """``record`` writes each episode's windows as they come; the shards are those that
    ``save_dataset`` writes of all the windows at once, however they were cut, and no more
    than a shard is ever held back."""
    monkeypatch.setattr(storage, "SHARD_SIZE", 16)
    pieces = [_windows(n, first) for n, first in ((5, 0), (16, 5), (40, 21), (1, 61), (9, 62))]
    whole = windows.Windows.concat(pieces)
    storage.save_dataset(windows.Dataset(whole, {"format": 1}), tmp_path / "whole")
    writer = storage.ShardWriter(tmp_path / "pieces")
    for piece in pieces:
        writer.add(piece)
        assert writer._buffered < 16
    writer.finish({"format": 1})
    assert _shard_digests(tmp_path / "pieces") == _shard_digests(tmp_path / "whole")
    assert [n for _, n, _ in _shard_digests(tmp_path / "whole")] == [16, 16, 16, 16, 7]
    back = storage.load_dataset(tmp_path / "pieces").windows
    for f in fields(windows.Windows):
        np.testing.assert_array_equal(getattr(back, f.name), getattr(whole, f.name))


def test_a_rolled_back_file_leaves_no_window_behind(tmp_path, monkeypatch):
    """A file of a group that fails half-way (after some of its shards were written) is
    skipped whole: the dataset is that of the other files alone. A file starts a shard (the
    mark writes what is buffered), so that its rollback is a number of shards."""
    monkeypatch.setattr(storage, "SHARD_SIZE", 8)
    kept_a, lost, kept_b = _windows(5, 0, "a/1"), _windows(30, 100, "b/1"), _windows(12, 7, "c/1")
    writer = storage.ShardWriter(tmp_path / "rolled")
    writer.add(kept_a)
    mark = writer.mark()
    assert mark == [1, ["a/1"]]  # kept_a written as a shard of its own
    writer.add(lost)
    assert len(writer.shards) == 4
    writer.rollback(mark)
    writer.add(kept_b)
    assert list(writer.tracks) == ["a/1", "c/1"]
    writer.finish({"format": 1})
    assert [n for _, n, _ in _shard_digests(tmp_path / "rolled")] == [5, 8, 4]
    back = storage.load_dataset(tmp_path / "rolled").windows
    both = windows.Windows.concat([kept_a, kept_b])
    for f in fields(windows.Windows):
        np.testing.assert_array_equal(getattr(back, f.name), getattr(both, f.name))
    assert sorted(p.name for p in (tmp_path / "rolled").iterdir()) == [
        "manifest.json", "shard-00000.npz", "shard-00001.npz", "shard-00002.npz"]  # fmt: skip


def test_a_split_recorded_as_it_comes_is_the_split_of_the_whole(tmp_path, monkeypatch):
    """``record --split`` keeps the side of the split by track that ``evaluate`` makes of the
    whole group (the same windows in the same shards), and leaves nothing aside."""
    monkeypatch.setattr(storage, "SHARD_SIZE", 32)
    whole = windows.record_group("us101_3_3", 1, stride=10)
    for side, half in zip(("train", "test"), windows.split_by_track(whole.windows, 0.3, 2),
                          strict=True):  # fmt: skip
        out = tmp_path / side
        manifest, tracks = recording.record_dataset(out, "us101_3_3", 1, seed=2, stride=10,
                                                  split=(side, 0.3))  # fmt: skip
        assert manifest["split"] == {"side": side, "test_fraction": 0.3, "seed": 2}
        assert tracks == len(np.unique(half.track)) and manifest["count"] == len(half)
        expected = windows.Dataset(half, {**whole.manifest, "split": manifest["split"]})
        storage.save_dataset(expected, tmp_path / f"{side}-whole")
        assert _shard_digests(out) == _shard_digests(tmp_path / f"{side}-whole")
        assert not (out / ".spool").exists()


def test_a_shard_unlike_the_others_is_named(tmp_path):
    storage.save_dataset(windows.Dataset(_windows(3), {"format": 1}), tmp_path / "d")
    shard = tmp_path / "d" / "shard-00001.npz"
    odd = _windows(2, 3)
    odd.grids = odd.grids[:, :, :4]
    write_npz(shard, compressed=True, **{f.name: getattr(odd, f.name) for f in fields(odd)})
    manifest = tmp_path / "d" / "manifest.json"
    doc = json.loads(manifest.read_text())
    sha = hashlib.sha256(shard.read_bytes()).hexdigest()
    doc["shards"].append({"file": shard.name, "windows": 2, "sha256": sha})
    doc["count"] = 5
    manifest.write_text(json.dumps(doc))
    with pytest.raises(windows.DatasetError, match=re.escape(
            f"{shard}: 'grids' is uint8 (2, 4, 8) per window, the first shard's uint8 "
            "(2, 8, 8)")):  # fmt: skip
        storage.load_dataset(tmp_path / "d")
    doc["count"] = 4
    manifest.write_text(json.dumps(doc))
    with pytest.raises(windows.DatasetError, match="more windows than the manifest's count 4"):
        storage.load_dataset(tmp_path / "d")
    doc["count"] = "5"
    manifest.write_text(json.dumps(doc))
    with pytest.raises(windows.DatasetError, match="'count' must be a positive integer, got '5'"):
        storage.load_dataset(tmp_path / "d")


def test_a_split_read_from_the_shards_is_the_split_of_the_whole(tmp_path, monkeypatch):
    """``evaluate`` reads each side of its split straight from the shards (every window held
    once): the same windows in the same order as splitting the whole dataset."""
    monkeypatch.setattr(storage, "SHARD_SIZE", 7)
    pieces = [_windows(n, first, f"s/{k}") for k, (n, first) in enumerate(
        ((5, 0), (9, 5), (3, 14), (12, 17), (4, 29), (6, 33)))]  # fmt: skip
    whole = windows.Windows.concat(pieces)
    storage.save_dataset(windows.Dataset(whole, {"format": 1}), tmp_path / "d")
    for seed in (0, 1, 2):
        manifest, train, test = storage.load_split(tmp_path / "d", 0.3, seed)
        assert manifest["count"] == len(whole)
        for read, split in zip((train, test), windows.split_by_track(whole, 0.3, seed),
                               strict=True):  # fmt: skip
            for f in fields(windows.Windows):
                np.testing.assert_array_equal(getattr(read, f.name), getattr(split, f.name))
    with pytest.raises(windows.DatasetError, match="need windows from >= 2 tracks"):
        storage.save_dataset(windows.Dataset(pieces[0], {"format": 1}), tmp_path / "one")
        storage.load_split(tmp_path / "one", 0.3, 0)


def _interrupt_at(monkeypatch, episode: int) -> None:
    """Ctrl-C while the ``episode``-th episode (from 1) of the next recording is driven."""
    ctrl_c_at(monkeypatch, windows, "_episode_windows", episode)


@pytest.mark.parametrize(
    ("scenario", "kwargs", "stop"),
    [("seamless", {"duration": 4.0}, 3), ("us101_3_3", {"stride": 10, "split": ("test", 0.3)}, 7)],
)
def test_an_interrupted_recording_goes_on_to_the_same_dataset(
    tmp_path, monkeypatch, scenario, kwargs, stop
):
    """``record`` leaves checkpoints as it goes; run again with the same arguments it goes on
    from the last one, and the dataset is the one recorded without a break, bit for bit."""
    monkeypatch.setattr(storage, "SHARD_SIZE", 8)
    monkeypatch.setattr(recording, "CHECKPOINT_SECONDS", 0.0)
    whole, _ = recording.record_dataset(tmp_path / "whole", scenario, 5, seed=3, **kwargs)
    with monkeypatch.context() as m:
        _interrupt_at(m, stop)
        with pytest.raises(KeyboardInterrupt):
            recording.record_dataset(tmp_path / "part", scenario, 5, seed=3, resume=True, **kwargs)
    checkpoint = tmp_path / "part" / (".spool" if "split" in kwargs else "") / "progress.json"
    assert json.loads(checkpoint.read_text())["state"]["episode"] == stop - 1
    said = []
    again, _ = recording.record_dataset(tmp_path / "part", scenario, 5, seed=3, resume=True,
                                      log=said.append, **kwargs)  # fmt: skip
    assert "going on with the interrupted recording" in said[0]
    assert _shard_digests(tmp_path / "part") == _shard_digests(tmp_path / "whole")
    assert {k: v for k, v in again.items() if k != "versions"} == {
        k: v for k, v in json.loads(json.dumps(whole)).items() if k != "versions"}  # fmt: skip
    assert sorted(p.name for p in (tmp_path / "part").iterdir()) == sorted(
        p.name for p in (tmp_path / "whole").iterdir())  # fmt: skip


def test_a_recording_of_other_arguments_is_refused_and_kept(tmp_path, monkeypatch):
    """An interrupted recording is not thrown away for a changed argument (a typo would lose
    hours of work): the refusal names what differs, and the same arguments go on with it."""
    from gridsim.errors import WorkKept

    monkeypatch.setattr(recording, "CHECKPOINT_SECONDS", 0.0)
    with monkeypatch.context() as m:
        _interrupt_at(m, 2)
        with pytest.raises(KeyboardInterrupt):
            recording.record_dataset(tmp_path / "d", "seamless", 3, seed=1, duration=3.0,
                                   resume=True)  # fmt: skip
    kept = sorted(p.name for p in (tmp_path / "d").iterdir())
    with pytest.raises(WorkKept, match=re.escape(
            f"{tmp_path / 'd'} holds an interrupted recording that was made with --seed 1 (now "
            f"2): give the arguments it was made with to go on with it, or remove "
            f"{tmp_path / 'd'} to start afresh")):  # fmt: skip
        recording.record_dataset(tmp_path / "d", "seamless", 3, seed=2, duration=3.0,
                                 resume=True)  # fmt: skip
    with pytest.raises(WorkKept, match="was made with --stride not given \\(now 2\\)"):
        recording.record_dataset(tmp_path / "d", "seamless", 3, seed=1, duration=3.0,
                                 stride=2, resume=True)  # fmt: skip
    with pytest.raises(WorkKept, match="was made without --split \\(now with\\)"):
        recording.record_dataset(tmp_path / "d", "seamless", 3, seed=1, duration=3.0,
                                 resume=True, split=("train", 0.3))  # fmt: skip
    assert sorted(p.name for p in (tmp_path / "d").iterdir()) == kept
    # one interrupted by a version that took windows by other rules (no window_rules)
    progress = tmp_path / "d" / recording.PROGRESS_FILE
    doc = json.loads(progress.read_text())
    older = {**doc, "arguments": {k: v for k, v in doc["arguments"].items()
                                  if k != "window_rules"}}  # fmt: skip
    progress.write_text(json.dumps(older))
    with pytest.raises(
        WorkKept,
        match=r"was made with other rules for taking windows \(1, now "
        r"2: a recorded track's episode drives on past",
    ):
        recording.record_dataset(tmp_path / "d", "seamless", 3, seed=1, duration=3.0,
                                 resume=True)  # fmt: skip
    progress.write_text(json.dumps(doc))
    # another --scenario (no --name): named as the flag given (it said --name)
    with pytest.raises(WorkKept, match=r"was made with --scenario seamless \(now inner_city\)"):
        recording.record_dataset(tmp_path / "d", "inner_city", 3, seed=1, duration=3.0,
                                 resume=True)  # fmt: skip
    said = []
    recording.record_dataset(tmp_path / "d", "seamless", 3, seed=1, duration=3.0, resume=True,
                           log=said.append)  # fmt: skip
    assert "going on with the interrupted recording" in said[0]
    assert not (tmp_path / "d" / "progress.json").exists()


def _record_interrupted(tmp_path, monkeypatch, scenario) -> None:
    """A recording of 3 episodes of ``scenario`` into ``tmp_path / "d"``, interrupted in its
    second (checkpoints after every episode from now on)."""
    monkeypatch.setattr(recording, "CHECKPOINT_SECONDS", 0.0)
    with monkeypatch.context() as m:
        _interrupt_at(m, 2)
        with pytest.raises(KeyboardInterrupt):
            recording.record_dataset(tmp_path / "d", str(scenario), 3, duration=3.0, resume=True)


def test_a_scenario_file_changed_after_a_break_is_named(tmp_path, monkeypatch):
    """A scenario file written again with the same contents goes on; other contents are
    named."""
    from gridsim.errors import WorkKept

    scenario = tmp_path / "mine.yaml"
    scenario.write_text("name: mine\nroad: {type: seamless}\n")
    _record_interrupted(tmp_path, monkeypatch, scenario)
    scenario.write_text("name: mine\nroad: {type: seamless}\n")  # the same, written again
    with monkeypatch.context() as m:
        _interrupt_at(m, 1)
        with pytest.raises(KeyboardInterrupt):
            recording.record_dataset(tmp_path / "d", str(scenario), 3, duration=3.0, resume=True)
    scenario.write_text("name: mine\nroad: {type: seamless}\nsensor: {rows: 128}\n")
    with pytest.raises(
        WorkKept, match=rf"made with other input files \(changed: {re.escape(str(scenario))}\)"
    ):
        recording.record_dataset(tmp_path / "d", str(scenario), 3, duration=3.0, resume=True)


def test_a_track_library_changed_after_a_break_is_named(tmp_path, monkeypatch):
    """The files a scenario names count too: a recording whose traffic library was edited
    after the break is refused, naming the library (it went on with the old windows)."""
    import shutil
    from importlib import resources

    from gridsim.errors import WorkKept

    shipped = resources.files("gridsim").joinpath("data", "ngsim", "ngsim_trajectories.csv")
    library = tmp_path / "tracks.csv"
    shutil.copyfile(str(shipped), library)
    scenario = tmp_path / "mine.yaml"
    scenario.write_text("name: mine\nroad: {type: seamless}\ntraffic: {library: [tracks.csv]}\n")
    _record_interrupted(tmp_path, monkeypatch, scenario)
    library.write_text(library.read_text() + "\n")  # an empty line more: other contents
    with pytest.raises(
        WorkKept, match=rf"other input files \(changed: {re.escape(str(library))}\)"
    ):
        recording.record_dataset(tmp_path / "d", str(scenario), 3, duration=3.0, resume=True)
    stamps = recording.group_inputs(str(scenario), None)
    assert set(stamps) == {str(scenario), str(library)}


def test_a_selection_reads_the_grids_it_is_asked_for_without_a_copy():
    """The warm start splits its windows by track with ``select``: the same windows as
    ``take``, but the grids (nearly all the memory) stay the dataset's until a batch reads
    them, so a split does not hold the dataset twice."""
    whole = _windows(40)
    rows = np.array([3, 5, 7, 11, 13, 17, 19, 23])
    picked, copied = whole.select(rows), whole.take(rows)
    assert picked.grids.base is whole.grids and picked.grids.shape == copied.grids.shape
    again = picked.select(np.array([6, 1, 2]))  # a selection of a selection: still the base
    assert again.grids.base is whole.grids
    np.testing.assert_array_equal(again.grids[np.arange(3)], copied.grids[[6, 1, 2]])
    for f in fields(windows.Windows):
        np.testing.assert_array_equal(np.asarray(getattr(picked, f.name)),
                                      getattr(copied, f.name))  # fmt: skip
    both = windows.Windows.concat([picked, whole.take(rows[:2])])  # (DAgger: copied then)
    np.testing.assert_array_equal(both.grids, np.concatenate([copied.grids, copied.grids[:2]]))


def _group_of_three(tmp_path: Path) -> Path:
    """A folder of three small recorded scenes (a group of files)."""
    folder = tmp_path / "group"
    folder.mkdir()
    data = Path(__file__).parents[2] / "data" / "commonroad"
    for name, copy in (("straight_2018b", "a"), ("straight_2020a", "b"), ("straight_2018b", "c")):
        (folder / f"{copy}.xml").write_bytes((data / f"{name}.xml").read_bytes())
    return folder


def _failing_first_file(folder: Path):
    """A stand-in for ``windows._episode_windows`` that fails on the third episode of the
    group ``folder``'s first file (and is a Ctrl-C at the call ``interrupt``), and the list
    its calls are counted in."""
    from gridsim.errors import ScenarioError

    files = windows.group_files("g", str(folder))[0]
    bad = (files[0], windows.scenario_episodes(files[0])[0][2].track)  # its third episode
    drive, calls = windows._episode_windows, []

    def failing(env, seed, stride, track, *args, interrupt=None, **kwargs):
        calls.append(1)
        if len(calls) == interrupt:
            raise KeyboardInterrupt
        if (str(env.scenario.source), track) == bad:
            raise ScenarioError("made up")
        return drive(env, seed, stride, track, *args, **kwargs)

    return failing, calls


def test_a_file_that_fails_after_a_break_is_skipped_whole(tmp_path, monkeypatch):
    """A file interrupted part-way and then failing when the recording goes on is rolled
    back to its start as recorded before the break: the dataset is the one an unbroken
    recording makes, which skips that file."""
    monkeypatch.setattr(storage, "SHARD_SIZE", 4)
    monkeypatch.setattr(recording, "CHECKPOINT_SECONDS", 0.0)
    folder = _group_of_three(tmp_path)
    files = windows.group_files("g", str(folder))[0]
    failing, calls = _failing_first_file(folder)
    monkeypatch.setattr(windows, "_episode_windows", failing)
    kwargs = {"source": str(folder), "stride": 5}
    with pytest.warns(Warning):
        whole, _ = recording.record_dataset(tmp_path / "whole", "g", 1, **kwargs)
    assert [s["file"] for s in whole["skipped"]] == [files[0]]
    calls.clear()
    monkeypatch.setattr(windows, "_episode_windows",
                        lambda *a, **k: failing(*a, interrupt=2, **k))  # fmt: skip
    with pytest.raises(KeyboardInterrupt):
        recording.record_dataset(tmp_path / "part", "g", 1, resume=True, **kwargs)
    monkeypatch.setattr(windows, "_episode_windows", failing)
    with pytest.warns(Warning):
        again, _ = recording.record_dataset(tmp_path / "part", "g", 1, resume=True, **kwargs)
    assert again["count"] == whole["count"]
    assert _shard_digests(tmp_path / "part") == _shard_digests(tmp_path / "whole")


def _bar() -> tuple[dict, dict]:
    """A progress bar's counts, and the ``planned`` and ``progress`` callbacks that move it."""
    counts = {"total": 0, "done": 0}

    def planned(n: int) -> None:
        counts["total"] += n

    def progress(n: int) -> None:
        counts["done"] += n

    return counts, {"planned": planned, "progress": progress}


def test_a_recording_gone_on_after_a_failed_file_counts_the_bar_as_unbroken(tmp_path, monkeypatch):
    """A file that failed before the break counts in the resumed bar as in an unbroken
    recording: all its episodes planned, those driven before it failed done."""
    monkeypatch.setattr(recording, "CHECKPOINT_SECONDS", 0.0)
    folder = _group_of_three(tmp_path)
    failing, calls = _failing_first_file(folder)
    monkeypatch.setattr(windows, "_episode_windows", failing)
    kwargs = {"source": str(folder), "stride": 10}
    whole, callbacks = _bar()
    with pytest.warns(Warning):
        recording.record_dataset(tmp_path / "whole", "g", 1, **kwargs, **callbacks)
    assert whole["total"] > whole["done"]  # (the failed file's episodes after it failed)
    calls.clear()
    monkeypatch.setattr(windows, "_episode_windows",
                        lambda *a, **k: failing(*a, interrupt=5, **k))  # fmt: skip
    with pytest.raises(KeyboardInterrupt), pytest.warns(Warning):  # the second file's 2nd
        recording.record_dataset(tmp_path / "part", "g", 1, resume=True, **kwargs)
    monkeypatch.setattr(windows, "_episode_windows", failing)
    again, callbacks = _bar()
    with pytest.warns(Warning):
        recording.record_dataset(tmp_path / "part", "g", 1, resume=True, **kwargs, **callbacks)
    assert again == whole


def test_a_recording_gone_on_with_counts_its_whole_bar(tmp_path, monkeypatch):
    """The progress bar of a recording that goes on after a break starts where it was: its
    total and its count at the end are those of a recording without a break (the files done
    before the break and the episodes of the file under way included)."""
    monkeypatch.setattr(recording, "CHECKPOINT_SECONDS", 0.0)
    kwargs = {"source": str(_group_of_three(tmp_path)), "stride": 10}
    whole, callbacks = _bar()
    recording.record_dataset(tmp_path / "whole", "g", 1, **kwargs, **callbacks)
    per_file = [len(windows.scenario_episodes(f)[0])
                for f in windows.group_files("g", kwargs["source"])[0]]  # fmt: skip
    assert whole == {"total": sum(per_file), "done": sum(per_file)}
    with monkeypatch.context() as m:
        _interrupt_at(m, per_file[0] + 2)  # the second file's second episode
        with pytest.raises(KeyboardInterrupt):
            recording.record_dataset(tmp_path / "part", "g", 1, resume=True, **kwargs)
    again, callbacks = _bar()
    recording.record_dataset(tmp_path / "part", "g", 1, resume=True, **kwargs, **callbacks)
    assert again == whole


def test_a_damaged_checkpoint_is_said_and_not_used(tmp_path, monkeypatch):
    monkeypatch.setattr(recording, "CHECKPOINT_SECONDS", 0.0)
    monkeypatch.setattr(storage, "SHARD_SIZE", 64)
    kwargs = {"duration": 4.0, "seed": 1}
    with monkeypatch.context() as m:
        _interrupt_at(m, 3)
        with pytest.raises(KeyboardInterrupt):
            recording.record_dataset(tmp_path / "d", "seamless", 4, resume=True, **kwargs)
    (pending,) = (tmp_path / "d").glob("pending-*.npz")
    pending.write_bytes(pending.read_bytes()[:100])
    said = []
    done, _ = recording.record_dataset(tmp_path / "d", "seamless", 4, resume=True,
                                     log=said.append, **kwargs)  # fmt: skip
    assert len(said) == 1 and "has a checkpoint that cannot be used (ValueError: " \
        f"{pending.name} was changed or truncated)" in said[0]  # fmt: skip
    whole, _ = recording.record_dataset(tmp_path / "whole", "seamless", 4, **kwargs)
    assert done["count"] == whole["count"]
    # a folder with files of its own is not emptied
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(windows.DatasetError, match="exists and is not empty"):
        recording.record_dataset(tmp_path / "mine", "seamless", 1, resume=True, **kwargs)
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep"


def test_the_dataset_folder_s_functions_are_still_found_where_they_were():
    with pytest.warns(
        DeprecationWarning,
        match="windows.load_dataset moved to neurotrajectory.data.storage.load_dataset",
    ):
        from neurotrajectory.data.windows import load_dataset
    assert load_dataset is storage.load_dataset
    with pytest.raises(AttributeError, match="has no attribute 'nothing'"):
        windows.nothing  # noqa: B018


def test_a_groups_bar_shows_its_total_once_every_file_is_planned():
    """Of a group of several files, the bar's total waits for the last file's plan (it grew
    file by file: 87 % 20/23, then 79 % 23/29 on urban), saying how many are still to plan."""
    import io

    from tqdm import tqdm

    bar = tqdm(file=io.StringIO())
    callbacks = windows.bar_callbacks(bar)
    seen = []

    def planned(count: int) -> None:
        callbacks["planned"](count)
        seen.append((bar.n, bar.total, bar.postfix))

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        windows.record_group("urban", 1, stride=40, **{**callbacks, "planned": planned})
    assert seen == [(0, None, "1 file still to plan"), (23, 29, "")]  # lankershim, peachtree
    assert bar.n == 29


def test_a_groups_source_names_ngsim_only_for_the_shipped_scenes():
    """A user's recorded data was labelled "human (NGSIM)" in the manifest and by evaluate."""
    source = windows._source
    assert source({"us101_3_3": True, "lankershim_1_1": True}) == "human (NGSIM)"
    assert source({"/data/mine.yaml": True}) == "human (recorded)"
    assert source({"seamless": False, "inner_city": False}) == "simulator"
    assert source({"us101_3_3": True, "seamless": False}) == "human (NGSIM) and simulator"
    assert source({"/data/mine.yaml": True, "us101_3_3": True}) == "human (recorded)"


def test_a_group_named_like_a_built_in_one_takes_its_source_from_its_files(tmp_path):
    """``record --scenario FOLDER --name highway`` of generated scenes said "human (NGSIM)"
    (the built-in group's); ``evaluate`` refuses a user group of a built-in name."""
    from neurotrajectory.cli import main
    from neurotrajectory.compare.evaluation import EvalConfig
    from neurotrajectory.data.windows import DatasetError

    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "a.yaml").write_text("extends: seamless\nname: a\n")
    out = tmp_path / "data"
    assert main(["record", "--scenario", str(tmp_path / "scenes"), "--name", "highway",
                 "--episodes", "1", "--episode-seconds", "3", "--out", str(out),
                 "--quiet"]) == 0  # fmt: skip
    assert json.loads((out / "manifest.json").read_text())["source"] == "simulator"
    with pytest.raises(DatasetError, match="'highway' is a built-in group"):
        EvalConfig(groups=("highway",), sources={"highway": str(tmp_path / "scenes")})


def test_only_a_recorded_tracks_episodes_drive_on_past_the_destination():
    """A recorded human crawls within the destination's tolerance of its end point for
    seconds: its episodes drive on (``env.end_at_destination`` off). A generated human
    reaches its end point only at its end: its episodes, and every dataset and warm start
    recorded from them, keep the scenario's ending (they changed with the first version)."""
    recorded, _ = scenario_episodes("us101_4_1")
    generated, _ = scenario_episodes("inner_city", 2, goal_seconds=5.0)
    assert all(e.overrides["env"]["end_at_destination"] is False for e in recorded)
    assert all(e.overrides["env"] == {"goal_seconds": 5.0} for e in generated)
    goal, _ = scenario_episodes("us101_4_1", goal_seconds=5.0)
    assert goal[0].overrides["env"] == {"goal_seconds": 5.0, "end_at_destination": False}


@pytest.mark.parametrize("orientation", ["north_up", "heading_up"])
def test_a_window_whose_label_starts_behind_the_ego_is_not_taken_on_its_own_track(orientation):
    """Driving a recorded human's own track, a window whose first set-point lies more than
    ``BEHIND`` behind the ego (it overshot a hard stop) is left out and counted; one just
    ahead, or a generated scene's, is taken; in either grid orientation."""
    from gridsim.frames import EGO_COS, EGO_SIN

    def take(scenario, overrides, shift):
        env = gym.make("GridSim-v0", scenario=scenario, sensor={"orientation": orientation},
                       **overrides).unwrapped  # fmt: skip
        obs, info = env.reset(seed=0)
        taker = windows._WindowTaker(1, None, False)
        taker.reset(env, info)
        ego = obs["ego"]
        heading = np.array([ego[EGO_COS], ego[EGO_SIN]])
        label = np.repeat((shift * heading)[None], 5, axis=0)  # every set-point there
        taker(env, obs, {**info, "reference_setpoints": label})
        return len(taker.rows), taker.behind

    track = {"ego": {"track": "422"}}
    assert take("us101_4_1", track, -windows.BEHIND - 0.05) == (0, 1)
    assert take("us101_4_1", track, -windows.BEHIND + 0.05) == (1, 0)
    assert take("seamless", {}, -1.0) == (1, 0)  # (a generated scene: taken as before)


@pytest.mark.parametrize(
    "scenario, overrides",
    [
        ("seamless", {}),
        ("us101_4_1", {"ego": {"track": "422"}, "env": {"end_at_destination": False}}),
    ],
)
def test_the_windows_not_taken_are_those_a_whole_episode_takes(scenario, overrides):
    """``missed`` at the start of an episode counts the windows the whole episode takes or
    leaves out behind the ego (driven by the reference to its time limit); on a generated
    scene the reference runs a horizon past the time limit and the count was one too many
    (the last observation, at the time limit, takes none)."""
    from gridsim.envs.episode import run_episode

    env = gym.make("GridSim-v0", scenario=scenario, simulation={"duration": 4.0},
                   **overrides).unwrapped  # fmt: skip
    taker = windows._WindowTaker(2, None, False)
    said = []
    episode = run_episode(env, taker, seed=3,
                          on_reset=lambda e, info: (taker.reset(e, info),
                                                    said.append(taker.missed(e))))  # fmt: skip
    assert episode.ended_by == "time limit"
    assert said == [len(taker.rows) + taker.behind] and len(taker.rows) > 0
