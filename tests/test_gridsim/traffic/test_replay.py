"""Recorded episodes as the human drove them: an ego track that waits is not "reached" at
once, but runs for its recorded duration."""

import warnings
from pathlib import Path

import numpy as np
import pytest
from scenes import track, waiting, write_scene

from gridsim.envs.gridsim_env import GridSimEnv
from gridsim.envs.human_reference import reference_from_track
from gridsim.traffic.fleet import EgoPose


def drive_reference(path: Path) -> tuple[GridSimEnv, dict, bool]:
    env = GridSimEnv(str(path))
    _, info = env.reset(seed=0)
    while True:
        _, _, terminated, truncated, info = env.step(info["reference_setpoints"])
        if terminated or truncated:
            return env, info, truncated


def test_a_reference_that_never_moves_is_never_reached():
    ref = reference_from_track(waiting(), 1.35)
    assert ref.length > 0.1  # the noise adds up along the path...
    assert ref.reach < 0.02  # ...but not away from the start
    assert not ref.reached(ref.xy[0], 0.0, 2.0)
    assert not ref.reached(ref.destination, 50.0, 2.0)
    moving = reference_from_track(track("m", np.linspace(0.0, 30.0, 31), np.zeros(31)), 1.35)
    assert moving.reached(moving.destination, 30.0, 2.0)
    assert not moving.reached(moving.destination, 10.0, 2.0)  # not without driving its length


def test_an_ego_that_waits_the_whole_time_runs_for_the_recorded_duration(tmp_path):
    env, info, truncated = drive_reference(write_scene(tmp_path, [waiting()]))
    assert truncated and not info["destination_reached"]
    assert env.world.time == pytest.approx(4.0)


def test_an_ego_that_waits_then_drives_off_is_reached_only_at_the_end(tmp_path):
    env, info, _ = drive_reference(write_scene(tmp_path, [waiting(61, moving_after=30)]))
    assert not info["collision"] and not info["off_road"]
    assert env.world.time >= 6.0 - 0.5  # within the tolerance of the end, not at the start


def test_a_track_file_edited_on_disk_is_read_again(tmp_path):
    """Even within its time stamps' resolution and at the same size (cache keys: stamps,
    and the content of files changed in the last seconds)."""
    import gymnasium as gym

    x = np.linspace(20.0, 60.0, 41)
    path = write_scene(tmp_path, [track("ego", x, np.full(41, -1.75))])
    env = gym.make("GridSim-v0", scenario=str(path))
    env.reset(seed=0)
    assert env.unwrapped.world.ego[1] == -1.75
    csv = tmp_path / "tracks.csv"
    before = csv.stat()
    csv.write_text(csv.read_text().replace("-1.75", "-1.77"))  # the same size
    assert csv.stat().st_size == before.st_size
    env.reset(seed=0)  # the same env, and a new one
    assert env.unwrapped.world.ego[1] == -1.77
    again = gym.make("GridSim-v0", scenario=str(path))
    again.reset(seed=0)
    assert again.unwrapped.world.ego[1] == -1.77


@pytest.mark.parametrize("shift", [0.0, 100.0, -5.0])
def test_the_traffic_replays_from_the_egos_first_recorded_time(tmp_path, shift):
    """The scene as the ego saw it: traffic at the ego's first time stamp, whatever the
    recording's clock (times from 100 s or below 0) and however late the ego entered (here
    3 s after the car ahead of it)."""
    from dataclasses import replace

    from scenes import track as crafted

    ahead = crafted("ahead", np.linspace(40.0, 100.0, 61), np.full(61, 1.75))  # 10 m/s, 6 s
    ego = crafted("ego", np.linspace(20.0, 50.0, 31), np.full(31, 1.75))
    ego = replace(ego, t=ego.t + 3.0)  # enters 3 s after the car ahead
    tracks = [replace(tr, t=tr.t + shift) for tr in (ahead, ego)]
    env = GridSimEnv(str(write_scene(tmp_path, tracks)))
    env.reset(seed=0)
    fleet = env.unwrapped.world.traffic.fleet
    assert fleet.active.sum() == 1
    assert fleet.x[0] == pytest.approx(70.0) and fleet.y[0] == pytest.approx(1.75)  # at 3 s
    env.step(env.unwrapped.reference_in_grid(np.array([0.5, 1.0, 1.5, 2.0, 2.5])))
    assert fleet.x[0] == pytest.approx(71.0)  # 0.1 s later


@pytest.mark.parametrize("library", [["parts"], ["parts/*.csv"], "parts"])
def test_a_library_may_be_a_folder_or_a_glob_of_trajectory_files(tmp_path, library):
    """A recording split into files (one per vehicle, per time window): ``traffic.library``
    takes their folder or a glob, as every other place that takes files does (in a list, or
    one alone)."""
    import yaml
    from scenes import track as crafted

    ahead = crafted("ahead", np.linspace(40.0, 100.0, 61), np.full(61, 1.75))
    ego = crafted("ego", np.linspace(20.0, 50.0, 31), np.full(31, 1.75))
    path = write_scene(tmp_path, [ahead, ego])
    rows = (tmp_path / "tracks.csv").read_text().splitlines()
    (tmp_path / "parts").mkdir()
    for name in ("ahead", "ego"):
        mine = [r for r in rows[1:] if r.split(",")[1] == name]
        (tmp_path / "parts" / f"{name}.csv").write_text("\n".join([rows[0], *mine]) + "\n")
    (tmp_path / "tracks.csv").unlink()
    doc = yaml.safe_load(path.read_text())
    doc["traffic"]["library"] = library
    path.write_text(yaml.safe_dump(doc))
    env = GridSimEnv(str(path))
    env.reset(seed=0)
    assert env.unwrapped.world.traffic.fleet.active.sum() == 1
    doc["traffic"]["library"] = ["nothing/*.csv"]
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(Exception, match=r"traffic.library 'nothing/\*.csv': no trajectory files"):
        GridSimEnv(str(path)).reset(seed=0)


def test_plausible_but_wrong_recordings_are_named(tmp_path):
    """A speed column of zeros (positions moving at 10 m/s), a size that changes from row to
    row, and a named ego track that grazes a road edge: each said, not silently used."""
    from dataclasses import replace

    import yaml
    from scenes import track as crafted

    from gridsim.errors import DataWarning
    from gridsim.scenario.checks import track_problems

    ahead = crafted("ahead", np.linspace(40.0, 100.0, 61), np.full(61, 1.75))
    still = replace(ahead, speed=np.zeros(61))
    assert any("its positions move at 10 m/s" in p and "recorded speeds say 0 m/s" in p
               for p in track_problems(still))  # fmt: skip
    assert track_problems(ahead) == []
    edge = crafted("edge", np.linspace(20.0, 50.0, 31), np.full(31, 3.2))  # 1.8 m wide
    path = write_scene(tmp_path, [ahead, edge])
    doc = yaml.safe_load(path.read_text())
    doc["ego"]["track"] = "edge"
    path.write_text(yaml.safe_dump(doc))
    with pytest.warns(DataWarning, match="ego.track edge is overlapping another or grazing a"):
        GridSimEnv(str(path)).reset(seed=0)
    rows = (tmp_path / "tracks.csv").read_text().splitlines()
    rows[5] = rows[5].replace(",4.5,", ",12.0,")  # one row of "ahead" says 12 m long
    (tmp_path / "tracks.csv").write_text("\n".join(rows) + "\n")
    from gridsim.traffic.library import read_tracks_csv

    with pytest.warns(DataWarning, match=r"1 track\(s\) change size .*: ahead \(4.5-12 x"):
        read_tracks_csv(tmp_path / "tracks.csv")


def test_vehicles_sized_in_feet_get_a_hint(tmp_path):
    from dataclasses import replace

    from scenes import track as crafted

    from gridsim.errors import GridSimError

    tracks = [replace(crafted(name, np.linspace(x, x + 30.0, 31), np.full(31, 1.75)),
                      length=14.8, width=5.9)  # 4.5 x 1.8 m in feet
              for name, x in (("ego", 20.0), ("other", 80.0))]  # fmt: skip
    hint = r"the scene.s median vehicle length is 14.8 m: are sizes and positions in metres"
    with pytest.raises(GridSimError, match=hint):
        GridSimEnv(str(write_scene(tmp_path, tracks, ego={"track": "random"}))).reset(seed=0)


def test_a_scene_of_trucks_in_metres_is_not_asked_about_feet(tmp_path):
    """Trucks (12 x 2.5 m) are longer than a random ego may be, but not wide enough for feet:
    the refusal says why they are unfit and does not ask about units (it did before 2026-11-27,
    when the scene's median length alone decided)."""
    from dataclasses import replace

    from scenes import track as crafted

    from gridsim.errors import GridSimError

    tracks = [replace(crafted(name, np.linspace(x, x + 30.0, 31), np.full(31, 1.75)),
                      length=12.0, width=2.5)
              for name, x in (("ego", 20.0), ("other", 80.0))]  # fmt: skip
    with pytest.raises(GridSimError, match=r"vehicle longer than 6 m") as refused:
        GridSimEnv(str(write_scene(tmp_path, tracks, ego={"track": "random"}))).reset(seed=0)
    assert "feet" not in str(refused.value)


def test_a_scene_s_tables_made_once_are_those_made_track_by_track():
    """Every episode of a recorded scene replays the same tracks: their path and profile
    tables are made once per scene and every world looks them up there (record builds one
    world per ego track; made per world, a scene of N tracks cost N^2). The banks are those
    that adding each track in turn makes, bit for bit; each world's participants replay the
    scene's slots of the tracks they are."""
    from gridsim.scenario.families.recorded import recorded_scene
    from gridsim.scenario.loader import load_scenario
    from gridsim.traffic.fleet import Fleet
    from gridsim.traffic.sources import RecordedSceneTraffic, track_path

    _, tracks = recorded_scene(load_scenario("us101_3_3"))
    one_by_one = Fleet(len(tracks))
    for tr in tracks:
        points, s, s_samples = track_path(tr)
        one_by_one.paths.add_path(points, s)
        prof = np.stack([s_samples, tr.speed, np.zeros_like(tr.t), tr.heading], axis=1)
        one_by_one.profiles.add(tr.t - tr.t[0], prof)
    fleets = []
    for exclude in (None, tracks[0].track_id, tracks[len(tracks) // 2].track_id):
        traffic = RecordedSceneTraffic(tracks, exclude=exclude)
        assert [tracks[k] for k in traffic.slots] == traffic.tracks
        assert [t.track_id for t in traffic.tracks] == [
            t.track_id for t in tracks if t.track_id != exclude]  # fmt: skip
        fleets.append(traffic.fleet)
    shared = fleets[0]
    for bank in ("paths", "profiles"):
        a, b = getattr(shared, bank).kernel_data(), getattr(one_by_one, bank).kernel_data()
        flat_a, flat_b = [*a[0], *a[1:]], [*b[0], *b[1:]]
        assert len(flat_a) == len(flat_b)
        for x, y in zip(flat_a, flat_b, strict=True):
            np.testing.assert_array_equal(x, y)
        assert all(getattr(f, bank) is getattr(shared, bank) for f in fleets)  # not made again
    np.testing.assert_array_equal(shared.paths.corridor_ids, one_by_one.paths.corridor_ids)


def test_a_track_starting_at_the_span_s_margin_is_placed_as_in_the_whole_scene():
    """A track recorded from exactly the margin past a world's span (25 Hz time stamps, where
    the clock's sum falls a hair short of the margin) is placed at the same tick as in a
    world that keeps every track: the world takes in the scene before it can be due."""
    import dataclasses

    from gridsim.traffic.sources import SPAN_MARGIN, RecordedSceneTraffic

    def car(tid: str, t0: float, n: int, y: float):
        tr = track(tid, 10.0 * 0.04 * np.arange(n) + 5 * int(tid), np.full(n, y), dt=0.04)
        return dataclasses.replace(tr, t=np.round(t0 + 0.04 * np.arange(n), 2))

    ego = car("0", 2.88, 126, 1.75)  # 2.88 .. 7.88 s
    tracks = [ego, car("1", 7.88 + SPAN_MARGIN, 100, 5.25), car("2", 3.0, 50, 8.75)]
    span = RecordedSceneTraffic(tracks, exclude="0", start_time=2.88, until=7.88)
    whole = RecordedSceneTraffic(tracks, exclude="0", start_time=2.88)
    pose = EgoPose(-100.0, 0.0, 0.0, 0.0, 4.5, 1.8)
    for source in (span, whole):
        source.reset(np.random.default_rng(0), pose)
    for _ in range(80):
        seen = []
        for source in (span, whole):
            source.tick(0.1, pose)
            f = source.fleet
            seen.append({source.tracks[i].track_id: (f.x[i], f.tau[i])
                         for i in np.flatnonzero(f.active)})  # fmt: skip
        assert seen[0] == seen[1]


def test_a_world_keeps_the_tracks_of_its_span_and_replays_them_as_the_whole_scene():
    """A world that replays an ego track's span keeps only the tracks recorded in it (a world
    of a scene of thousands of vehicles holds those it meets), and its participants move as
    in a world that keeps every track, bit for bit, past its span too (it then takes in the
    rest of the scene)."""
    import dataclasses

    from gridsim.traffic.sources import RecordedSceneTraffic

    tracks = []  # cars entering a three-lane road every 0.7 s, each recorded for 5 s
    for k in range(40):
        x = 10.0 * 0.1 * np.arange(51) + (k % 5)
        tr = track(str(k), x, np.full(51, 1.75 + 3.5 * (k % 3)))
        tracks.append(dataclasses.replace(tr, t=tr.t + 0.7 * k))
    ego = tracks[20]
    start, until = float(ego.t[0]), float(ego.t[-1])
    span = RecordedSceneTraffic(tracks, exclude=ego.track_id, start_time=start, until=until)
    whole = RecordedSceneTraffic(tracks, exclude=ego.track_id, start_time=start)
    assert 0 < len(span.tracks) < len(whole.tracks)
    met = [t.track_id for t in tracks
           if t.track_id != ego.track_id and t.t[0] <= until and t.t[-1] >= start]  # fmt: skip
    assert set(met) <= {t.track_id for t in span.tracks}
    pose = EgoPose(float(ego.x[0]), float(ego.y[0]), float(ego.heading[0]), 0.0, 4.5, 1.8)
    for source in (span, whole):
        source.reset(np.random.default_rng(0), pose)
    named = {t.track_id: i for i, t in enumerate(whole.tracks)}
    for _ in range(round((until - start) / 0.1) + 40):
        for source in (span, whole):
            source.tick(0.1, pose)
        f, g = span.fleet, whole.fleet
        mine = np.flatnonzero(f.active)
        theirs = [named[span.tracks[i].track_id] for i in mine]
        assert theirs == list(np.flatnonzero(g.active))
        for name in ("x", "y", "psi", "v", "s", "tau"):
            np.testing.assert_array_equal(getattr(f, name)[mine], getattr(g, name)[theirs])
    assert span.until is None and len(span.tracks) == len(whole.tracks)  # past its span


def test_a_scene_on_a_unix_epoch_clock_replays_as_the_same_scene_counted_from_0(tmp_path):
    """Time stamps of 1.7e9 s (a Unix-epoch clock, within the documented 1e10 s) resolve
    only 2.4e-7 s in float64: the traffic clock's tolerance is 1e-9 s, and vehicles were
    placed a tick early or late (the grids of US-101 differed in 81-363 cells from the same
    scene counted from 0, silently). Such a scene is counted from its first whole second,
    said in a warning, and replays as the same scene counted from 0, bit for bit."""
    from dataclasses import replace

    import gymnasium as gym

    from gridsim.traffic.library import RECOUNTED_FROM

    x = np.linspace(20.0, 80.0, 41)
    tracks = [track("ego", x, np.full(41, 1.75))]
    for k, start in enumerate((0.3, 0.7, 1.3, 2.1)):  # cars that come in at later ticks
        later = track(f"c{k}", x[: 41 - round(start * 10)] + 12.0 + 6 * k, np.full(41 - round(
            start * 10), -1.75))  # fmt: skip
        tracks.append(replace(later, t=later.t + start))
    runs = []
    for offset in (0.0, 1.7e9):
        folder = tmp_path / f"at{offset:g}"
        folder.mkdir()
        shifted = [replace(t, t=t.t + offset) for t in tracks]
        scenario = write_scene(folder, shifted)
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            env = gym.make("GridSim-v0", scenario=str(scenario)).unwrapped
            obs, info = env.reset(seed=0)
        epoch = [str(w.message) for w in said if "a Unix-epoch clock?" in str(w.message)]
        assert len(epoch) == (offset >= RECOUNTED_FROM)
        if epoch:
            assert "counted from the scene's first whole second (crafted from 1700000000 s" \
                in epoch[0]  # fmt: skip
        grids, active = [obs["grids"][-1].copy()], []
        for _ in range(30):
            obs, _, terminated, truncated, info = env.step(info["reference_setpoints"])
            grids.append(obs["grids"][-1].copy())
            active.append(int(env.world.traffic.fleet.active.sum()))
            if terminated or truncated:
                break
        runs.append((np.array(grids), active))
    (at_0, active_0), (at_epoch, active_epoch) = runs
    assert active_0 == active_epoch and max(active_0) == 4
    np.testing.assert_array_equal(at_0, at_epoch)
