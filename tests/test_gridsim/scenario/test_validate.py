"""Plausibility checks of recorded scenes (``gridsim validate``): crafted mistakes are named
with the file, the track and the numbers; the shipped scenes pass."""

import re
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from scenes import track, write_scene

from gridsim.cli import main
from gridsim.errors import DataError, DataWarning
from gridsim.scenario.checks import track_problems
from gridsim.scenario.families import scenario_problems
from gridsim.scenario.loader import load_scenario

X = np.linspace(20.0, 60.0, 41)  # 10 m/s along the right lane for 4 s


def validate(capsys, path) -> tuple[int, str]:
    code = main(["validate", str(path)])
    out = capsys.readouterr()
    return code, out.out + out.err


@pytest.mark.parametrize("name", ["us101_3_3", "us101_4_1", "lankershim_1_1", "peachtree_4_8"])
def test_shipped_scenes_are_plausible(name):
    assert scenario_problems(load_scenario(name)) == []


def test_a_good_crafted_scene_passes(tmp_path, capsys):
    code, out = validate(capsys, write_scene(tmp_path, [track("ego", X, np.full(41, -1.75))]))
    assert code == 0 and "OK" in out


def test_a_track_off_the_map_is_kept_as_traffic_with_a_warning(tmp_path, capsys):
    off = track("far", X + 500.0, np.full(41, 40.0))  # 500 m beyond the map's end
    path = write_scene(tmp_path, [track("ego", X, np.full(41, -1.75)), off],
                       ego={"track": "random"})  # fmt: skip
    code, out = validate(capsys, path)
    assert code == 0
    assert (f"warning: {tmp_path / 'tracks.csv'}: track far of scene crafted: 41 of its 41 "
            "positions (100%) are off the map's drivable area (at most 20%); kept as traffic, "
            "not offered as the ego" in out)  # fmt: skip
    assert "track ego" not in out
    with pytest.warns(DataWarning, match="track far of scene crafted: 41 of its 41 positions"):
        env = gym.make("GridSim-v0", scenario=str(path))
        for seed in range(6):  # never the ego, always in the traffic
            env.reset(seed=seed)
            assert env.unwrapped.world.ego_track.track_id == "ego"
            assert [t.track_id for t in env.unwrapped.world.traffic.tracks] == ["far"]
    with pytest.raises(DataError, match="ego.track far cannot be the ego: .* 41 of its 41"):
        gym.make("GridSim-v0", scenario=str(path), ego={"track": "far"}).reset(seed=0)


def test_a_scene_mostly_off_its_map_is_refused_everywhere(tmp_path, capsys):
    tracks = [track(f"far{k}", X + 500.0, np.full(41, 40.0 + 5 * k)) for k in range(3)]
    path = write_scene(tmp_path, [track("ego", X, np.full(41, -1.75)), *tracks])
    code, out = validate(capsys, path)
    assert code == 2
    assert "3 of its 4 tracks are implausible for this map or in the wrong units" in out
    assert "track far1 of scene crafted: 41 of its 41 positions (100%) are off" in out
    refused = r"implausible recorded scene \(1 problem\):\n.*3 of its 4 tracks"
    with pytest.raises(DataError, match=refused):
        gym.make("GridSim-v0", scenario=str(path)).reset(seed=0)


def test_a_file_of_another_map_beside_a_good_one_is_refused(tmp_path, capsys):
    """Each library file is judged on its own tracks: one whose tracks are all off the map is
    refused even where a good file's tracks outnumber them (its tracks were kept as traffic,
    3 of 7 flawed in the scene)."""
    (tmp_path / "o").mkdir()
    far = [track(f"far{k}", X + 500.0, np.full(41, 40.0 + 5 * k)) for k in range(3)]
    write_scene(tmp_path / "o", far)  # o/tracks.csv: another map's tracks
    good = [track(f"car{k}", X + 10.0 * k, np.full(41, -1.75)) for k in range(3)]
    path = write_scene(tmp_path, [track("ego", X - 15.0, np.full(41, -1.75)), *good],
                       traffic={"library": ["tracks.csv", "o/tracks.csv"]})  # fmt: skip
    code, out = validate(capsys, path)
    assert code == 2
    assert f"{tmp_path / 'o' / 'tracks.csv'}: 3 of its 3 tracks are implausible for this " \
        "map" in out  # fmt: skip
    assert f"{tmp_path / 'tracks.csv'}: " not in out  # the good file is not named
    # one odd track in a file of its own (a library of one CSV per vehicle) is kept as traffic
    write_scene(tmp_path / "o", far[:1])
    code, out = validate(capsys, path)
    assert code == 0 and "track far0 of scene crafted: 41 of its 41 positions" in out


def test_time_in_steps_instead_of_seconds_is_caught(tmp_path, capsys):
    tr = track("ego", X, np.full(41, -1.75), dt=1.0)  # time stamps 0, 1, 2, ...: steps
    tr.speed[:] = 10.0  # the recorded speed is right
    code, out = validate(capsys, write_scene(tmp_path, [tr]))
    assert code == 2
    assert "track ego of scene crafted: positions and time stamps imply 1 m/s where" in out
    assert "recorded speeds say 10 m/s (median, ratio 0.1)" in out
    assert "its time step is 1 s: a CSV's time column, a CommonRoad file's timeStepSize" in out


def test_time_stamps_that_jitter_around_their_step_are_said(tmp_path, capsys):
    """Time stamps jittering by +-3 ms (a logger's clock) move vehicles in and out a tick:
    on US-101 up to 10,355 cells of a window's grids and 5 of 663 windows changed, and
    nothing said so. A warning does; a clean 10 Hz recording, or one at 20 Hz, says nothing."""
    from dataclasses import replace

    clean = track("ego", X, np.full(41, -1.75))
    jitter = np.random.default_rng(0).uniform(-0.003, 0.003, 41)
    jitter[0] = 0.0
    code, out = validate(capsys, write_scene(tmp_path, [replace(clean, t=clean.t + jitter)]))
    assert code == 0
    assert re.search(r"the time stamps of 1 of its 1 tracks jitter by up to [\d.]+ ms "
                     r"around their 0\.1 s step \(a logger's clock\?\)", out)  # fmt: skip
    for n, dt in ((41, 0.1), (81, 0.05)):  # 10 and 20 Hz over the same 4 s
        steady = track("ego", np.linspace(X[0], X[-1], n), np.full(n, -1.75), dt=dt)
        code, out = validate(capsys, write_scene(tmp_path, [steady]))
        assert code == 0 and "jitter by" not in out


def test_time_in_frames_with_speeds_per_frame_is_asked_about(tmp_path, capsys):
    """Frame numbers for time and speeds in metres per frame agree with the positions, so no
    track check sees them; the scene would replay ten times too slowly: a warning asks."""
    lanes = (("ego", -1.75), ("car", 1.75))
    slow = [track(name, X[::10], np.full(5, y), dt=1.0) for name, y in lanes]
    code, out = validate(capsys, write_scene(tmp_path, slow))
    assert "its tracks are sampled every 1 s (median): is the time column in seconds, not " \
        "frame numbers?" in out  # fmt: skip
    code, out = validate(capsys, write_scene(tmp_path, [track("ego", X, np.full(41, -1.75))]))
    assert code == 0 and "sampled every" not in out  # 10 Hz: nothing asked


def test_implausible_speeds_and_accelerations_are_caught():
    x = np.cumsum(np.full(41, 9.0))  # 90 m/s, consistent with its speed column
    problems = track_problems(track("fast", x, np.zeros(41)))
    assert len(problems) == 1 and "imply 90 m/s (95th percentile; at most 70)" in problems[0]
    jerky = np.cumsum(np.tile([0.1, 0.5], 20))  # 1 <-> 5 m/s every 0.1 s: 40 m/s^2
    problems = track_problems(track("jerky", jerky, np.zeros(40)))
    assert any("accelerations of 40 m/s^2 (median; at most 15)" in p for p in problems)


def test_length_and_width_swapped_and_speeds_in_feet_per_second_are_named():
    """A car 1.8 m long and 4.5 m wide straddled lanes without a word; speeds in ft/s (ratio
    0.305, 10 % from km/h's 0.278) were said to be in km/h or time in steps, track by track."""
    import dataclasses

    fine = track("car", X, np.full(41, -1.75))
    swapped = dataclasses.replace(fine, track_id="swapped", length=1.8, width=4.5)
    (problem,) = track_problems(swapped)
    assert "it is 4.5 m wide and 1.8 m long: are its length and width swapped?" in problem
    for unit, factor, said in (("ft/s", 1 / 0.3048, "ft/s x 0.3048"), ("km/h", 3.6, "km/h / 3.6"),
                               ("mph", 1 / 0.44704, "mph x 0.44704")):  # fmt: skip
        (problem,) = track_problems(dataclasses.replace(fine, speed=fine.speed * factor))
        assert problem.endswith(f"its speeds must be in m/s ({said})"), unit


def test_a_scene_too_short_for_the_horizon_is_caught(tmp_path, capsys):
    short = track("ego", X[:21], np.full(21, -1.75))  # 2 s; the horizon needs 5 x 0.5 s
    code, out = validate(capsys, write_scene(tmp_path, [short]))
    assert code == 2
    assert "scene crafted lasts 2 s (its longest track, ego); the horizon needs 2.5 s" in out
    assert "ego.track ego lasts 2 s" in out


def test_a_heading_against_the_motion_is_a_flaw():
    backwards = track("back", X, np.full(41, -1.75), heading=np.pi)  # drives +x, heading -x
    (problem,) = track_problems(backwards)
    assert "it drives 180 degrees off its recorded heading (median; at most 45)" in problem
    assert "(it is 3.14 rad at every sample: is its heading column filled in?)" in problem
    assert track_problems(track("fine", X, np.full(41, -1.75))) == []
    # a heading column left at 0 on a road at -43 degrees passed the 45-degree test
    angle = np.radians(-43.0)
    diagonal = track("zeros", X * np.cos(angle), X * np.sin(angle), heading=0.0)
    (problem,) = track_problems(diagonal)
    assert ("its recorded heading is 0 rad at every sample while it drives 43 degrees off it "
            "(median); is its heading column filled in?") in problem  # fmt: skip
    assert track_problems(track("filled", X * np.cos(angle), X * np.sin(angle), angle)) == []


def test_a_position_that_leaps_off_its_neighbours_is_a_flaw(tmp_path, capsys):
    """A one-sample glitch at a plausible speed (20 m/s into it, back out of it) is named; the
    shipped tracks' noise is not (test_shipped_scenes_are_plausible)."""
    y = np.full(41, -1.75)
    y[20] += 2.0
    (problem,) = track_problems(track("spike", X, y))
    assert ("its position at t = 2 s leaps 2 m off the line between its neighbours (the "
            "velocity turns at 400 m/s^2 there; at most 100)") in problem  # fmt: skip
    jumped = X + np.where(np.arange(41) >= 25, 3.0, 0.0)  # a 3 m jump that stays
    (problem,) = track_problems(track("jump", jumped, np.full(41, -1.75)))
    assert "its position at t = 2.4 s leaps 1.5 m" in problem
    path = write_scene(tmp_path, [track("ego", X, np.full(41, -1.75)), track("spike", X + 10, y)],
                       ego={"track": "random"})  # fmt: skip
    code, out = validate(capsys, path)
    assert code == 0 and "track spike of scene crafted: its position at t = 2 s leaps" in out
    assert "kept as traffic, not offered as the ego" in out


def test_speeds_in_km_h_and_swapped_coordinates_get_their_own_hint():
    kmh = track("kmh", X, np.full(41, -1.75))
    kmh.speed[:] = 36.0  # 10 m/s recorded in km/h
    (problem,) = track_problems(kmh)
    assert "recorded speeds say 36 m/s (median, ratio 0.278); its speeds must be in m/s" in problem
    assert "must be in seconds" not in problem
    mph = track("mph", X, np.full(41, -1.75))
    mph.speed[:] = 10.0 / 0.44704  # 10 m/s recorded in mph
    (problem,) = track_problems(mph)
    assert problem.endswith("(median, ratio 0.447); its speeds must be in m/s (mph x 0.44704)")
    feet = track("feet", X / 0.3048, np.full(41, -1.75 / 0.3048))
    feet.speed[:] = 10.0  # 10 m/s, positions in feet
    assert any(p.endswith("its positions must be in metres (feet x 0.3048)")
               for p in track_problems(feet))  # fmt: skip
    swapped = track("swapped", np.full(41, 5.0), X)  # drives +y, its heading says +x
    (problem,) = track_problems(swapped)
    assert "it drives 90 degrees off its recorded heading" in problem
    assert "(or are its x and y swapped? with them swapped it drives 0 degrees off)" in problem


def test_tracks_that_share_no_moment_are_named(tmp_path, capsys):
    """Every track but one shifted by 100 s (recordings of other clocks in one scene): as the
    ego, such a track meets no traffic."""
    tracks = [track(f"c{k}", X, np.full(41, -1.75 if k % 2 else 1.75)) for k in range(4)]
    for k, tr in enumerate(tracks[1:], 1):
        tr.t[:] += 100.0 * k
    path = write_scene(tmp_path, tracks, ego={"track": "random"})
    code, out = validate(capsys, path)
    assert code == 0
    said = (
        "4 of the 4 tracks of scene crafted share no moment with any other (c0, c1, c2, "
        "c3): as the ego they meet no traffic; are their time stamps from one clock?"
    )
    assert said in out
    together = write_scene(tmp_path, [track(f"c{k}", X, np.full(41, 1.75 - 3.5 * (k % 2)))
                                      for k in range(2)], ego={"track": "random"})  # fmt: skip
    code, out = validate(capsys, together)
    assert code == 0 and "share no moment" not in out


def test_tracks_alone_in_time_are_found_as_by_comparing_every_pair():
    """The n log n search (22,000 tracks took 1 GB by pairs) against all pairs, ties included."""
    from gridsim.scenario.checks import _alone_in_time

    rng = np.random.default_rng(0)
    for _ in range(200):
        n = int(rng.integers(2, 30))
        tracks = []
        for k in range(n):
            samples = int(rng.integers(2, 8))
            tr = track(f"c{k}", np.linspace(0.0, 10.0, samples), np.zeros(samples))
            tr.t[:] = float(rng.integers(0, 50)) + np.arange(samples)
            tracks.append(tr)
        start, end = np.array([t.t[0] for t in tracks]), np.array([t.t[-1] for t in tracks])
        meets = (start[:, None] <= end[None, :]) & (start[None, :] <= end[:, None])
        alone = np.flatnonzero(meets.sum(axis=1) == 1)
        found = _alone_in_time(tracks, "s")
        assert bool(found) == (len(alone) > 0.5 * n)
        if found:
            assert f"{len(alone)} of the {n} tracks" in found[0]
            assert ", ".join(tracks[k].track_id for k in alone[:5]) in found[0]


def _library_scenario(tmp_path, wrong: set[str] | None) -> str:
    """A seamless scenario whose traffic.library is the shipped CSV with speeds in km/h, for
    every track (``wrong`` None) or the tracks named."""
    import csv
    from importlib import resources

    source = resources.files("gridsim").joinpath("data", "ngsim", "ngsim_trajectories.csv")
    rows = list(csv.DictReader(source.read_text().splitlines()))
    with (tmp_path / "kmh.csv").open("w", newline="") as fh:
        out = csv.DictWriter(fh, fieldnames=list(rows[0]))
        out.writeheader()
        for r in rows:
            if wrong is None or r["track_id"] in wrong:
                r = {**r, "speed_mps": f"{float(r['speed_mps']) * 3.6:.4f}"}
            out.writerow(r)
    path = tmp_path / "mine.yaml"
    path.write_text("name: mine\nroad: {type: seamless}\ntraffic: {library: [kmh.csv]}\n")
    return str(path)


def test_a_generated_roads_library_in_other_units_is_refused(tmp_path, capsys):
    """The library's tracks give a generated road's speed profiles: speeds in km/h (or time
    in steps, headings in degrees) loaded silently and changed every episode's traffic; the
    checks that need no map now run on them too."""
    path = _library_scenario(tmp_path, None)
    with pytest.raises(DataError, match=r"implausible traffic.library \(its tracks give the "
                       r"speed profiles\).*\n.* tracks are implausible or in the wrong units "
                       r".*\n.*its speeds must be in m/s \(km/h / 3.6\)"):  # fmt: skip
        gym.make("GridSim-v0", scenario=path).reset(seed=0)
    assert main(["validate", path]) == 2
    assert "its speeds must be in m/s (km/h / 3.6)" in capsys.readouterr().err


def test_a_flawed_library_track_is_not_used_as_a_speed_profile(tmp_path):
    from gridsim.scenario.parts import synthetic_tracks

    path = _library_scenario(tmp_path, {"1213"})
    sc = load_scenario(path)
    with pytest.warns(DataWarning, match=r"track 1213 of scene .*must be in m/s \(km/h / 3.6\); "
                      r"not used as a speed profile"):  # fmt: skip
        used = synthetic_tracks(sc)
    assert "1213" not in {t.track_id for t in used}
    assert len(used) == len(synthetic_tracks(load_scenario("seamless"))) - 1


def test_a_library_report_made_once_is_still_said_and_names_its_scenario(tmp_path):
    """The library's report is made once per library and scenario (each reset of a generated
    road asked for it: 1.6 ms a reset); every selection still warns, in the scenario's name,
    and the same library under another scenario file gets a report naming that file."""
    from gridsim.scenario.parts import synthetic_tracks

    path = _library_scenario(tmp_path, {"1213"})
    other = tmp_path / "other.yaml"
    other.write_text(Path(path).read_text().replace("name: mine", "name: other"))
    for source in (path, path, str(other)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            used = synthetic_tracks(load_scenario(source))
        (said,) = [str(w.message) for w in caught if issubclass(w.category, DataWarning)]
        assert said.startswith(f"{tmp_path / 'kmh.csv'}: track 1213 of scene")
        assert "1213" not in {t.track_id for t in used}


def test_a_library_of_many_files_with_notes_warns_once(tmp_path):
    """A library of one CSV per vehicle, each with a row given twice: one warning, the first
    files' notes in full and the others named (one warning per file filled the screen)."""
    from gridsim.scenario import parts

    header = "scenario_id,track_id,time_s,x_m,y_m,heading_rad,speed_mps,length_m,width_m"
    (tmp_path / "lib").mkdir()
    for k in range(8):
        rows = [f"s,{k},{i * 0.1:.1f},{i * 1.0:g},0,0,10,4.5,1.8" for i in range(30)]
        (tmp_path / "lib" / f"veh_{k}.csv").write_text("\n".join([header, *rows, rows[-1]]))
    path = tmp_path / "mine.yaml"
    path.write_text("name: mine\nroad: {type: seamless}\ntraffic: {library: [lib]}\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert len(parts.library_for(load_scenario(path)).tracks) == 8
    (said,) = [str(w.message) for w in caught if issubclass(w.category, DataWarning)]
    # (named with the scenario that reads the library: it did not say whose library)
    assert said.startswith(f"{path}: traffic.library: 8 of its 8 trajectory files have notes; "
                           "the first 5")  # fmt: skip
    assert said.count("repeat an earlier one exactly") == parts.NOTES_SHOWN
    assert "and likewise: " in said and f"{tmp_path / 'lib' / 'veh_7.csv'}" in said


def test_a_library_folder_skips_the_files_it_cannot_read(tmp_path):
    """A folder of daily trajectory files with an empty one and one cut mid-line: both are
    named in one warning and the rest is used (one bad file made the whole library, and so
    the scenario, unusable); a file named on its own is still refused, as is a folder of
    which no file can be read."""
    from importlib import resources

    from gridsim.scenario.parts import library_for

    source = resources.files("gridsim").joinpath("data", "ngsim", "ngsim_trajectories.csv")
    lines = source.read_text().splitlines()
    (tmp_path / "days").mkdir()
    (tmp_path / "days" / "a.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "days" / "b.csv").write_text("")
    (tmp_path / "days" / "c.csv").write_text(
        "\n".join([*lines[:3], lines[3][:20], *lines[4:6]]) + "\n"
    )  # (one cut at the very end: read)
    path = tmp_path / "mine.yaml"
    path.write_text("name: mine\nroad: {type: seamless}\ntraffic: {library: [days]}\n")
    said = r"skipped 2 of 3 trajectory files that cannot be read:\n  - .*b.csv: the file is empty"
    with pytest.warns(DataWarning, match=said + r".*\n  - .*c.csv:4: "):
        tracks = library_for(load_scenario(path)).tracks
    assert len(tracks) == len(library_for(load_scenario("seamless")).tracks)
    path.write_text("name: mine\nroad: {type: seamless}\ntraffic: {library: [days/b.csv]}\n")
    with pytest.raises(DataError, match=r"b.csv: the file is empty"):
        library_for(load_scenario(path))
    (tmp_path / "days" / "a.csv").unlink()
    path.write_text("name: mine\nroad: {type: seamless}\ntraffic: {library: [days]}\n")
    with pytest.raises(DataError, match=r"traffic.library: none of its 2 files can be read"):
        library_for(load_scenario(path))


def test_a_dataset_s_manifest_lists_the_library_files_left_out(tmp_path, capsys):
    """``record``'s manifest lists, under ``skipped``, the ``traffic.library`` files of a
    folder left out because they cannot be read (its ``inputs`` listed them with their
    digests, as if they were used; only a warning said otherwise)."""
    from importlib import resources

    from neurotrajectory.cli import main as nt_main
    from neurotrajectory.data.storage import load_dataset

    source = resources.files("gridsim").joinpath("data", "ngsim", "ngsim_trajectories.csv")
    (tmp_path / "days").mkdir()
    (tmp_path / "days" / "a.csv").write_text(source.read_text())
    (tmp_path / "days" / "b.csv").write_text("")
    path = tmp_path / "mine.yaml"
    path.write_text("name: mine\nroad: {type: seamless}\ntraffic: {library: [days]}\n")
    code = nt_main(["record", "--scenario", str(path), "--out", str(tmp_path / "ds"),
                    "--episodes", "1", "--episode-seconds", "4", "--quiet"])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    (skipped,) = load_dataset(tmp_path / "ds").manifest["skipped"]
    assert skipped == {"file": str(tmp_path / "days" / "b.csv"),
                       "reason": "a traffic.library file that cannot be read: the file is "
                                 "empty; a trajectory CSV starts with the header "
                                 "scenario_id,track_id,time_s,x_m,y_m,heading_rad,speed_mps,"
                                 "length_m,width_m"}  # fmt: skip


def test_validate_says_how_many_tracks_a_random_ego_is_not_drawn_from(capsys):
    """`record` drives every track as the ego, trucks too, and warns of those a random ego is
    not drawn from: validate counts them with the reasons (it said only OK)."""
    code, out = validate(capsys, "us101_3_3")
    assert code == 0
    assert "builtin:us101_3_3: 2 of its 12 tracks are not drawn as a random ego (2 of a " \
        "vehicle longer than 6 m)" in out  # fmt: skip
    with warnings.catch_warnings():  # gym.make does not warn of it
        warnings.simplefilter("error", DataWarning)
        gym.make("GridSim-v0", scenario="us101_3_3").reset(seed=0)


def test_a_generated_roads_library_in_feet_is_named(tmp_path, capsys):
    """Sizes and positions in feet: no track is short enough for the default length limit
    (the error says why), and a limit raised to let them in gets a warning (cars 15 m long
    otherwise drove silently)."""
    import csv
    from importlib import resources

    source = resources.files("gridsim").joinpath("data", "ngsim", "ngsim_trajectories.csv")
    rows = list(csv.DictReader(source.read_text().splitlines()))
    feet = ("x_m", "y_m", "speed_mps", "length_m", "width_m")
    with (tmp_path / "feet.csv").open("w", newline="") as fh:
        out = csv.DictWriter(fh, fieldnames=list(rows[0]))
        out.writeheader()
        out.writerows({**r, **{k: f"{float(r[k]) * 3.28084:.4f}" for k in feet}} for r in rows)
    path = tmp_path / "mine.yaml"
    path.write_text("name: mine\nroad: {type: seamless}\ntraffic: {library: [feet.csv]}\n")
    code, out = validate(capsys, path)
    assert code == 2 and "the median vehicle length is 16 m: are sizes and positions in " \
        "metres (not feet)?" in out  # fmt: skip
    path.write_text("name: mine\nroad: {type: seamless}\n"
                    "traffic: {library: [feet.csv], max_vehicle_length: 25}\n")  # fmt: skip
    code, out = validate(capsys, path)
    assert code == 0 and "traffic.library: the median vehicle length is" in out
    with pytest.warns(DataWarning, match="are sizes and positions in metres"):
        gym.make("GridSim-v0", scenario=str(path)).reset(seed=0)


def test_trucks_in_metres_are_not_taken_for_feet():
    """The feet hint needs vehicles both too long and too wide for metres: a library of trucks
    (12 x 2.5 m) is not asked whether it is in feet; 15 x 6 (feet for 4.5 x 1.8 m) is."""
    import dataclasses

    from gridsim.scenario.checks import feet_hint

    car = track("c", X, np.full(41, -1.75))
    trucks = [dataclasses.replace(car, track_id=f"t{k}", length=12.0, width=2.5) for k in range(3)]
    assert feet_hint(trucks) == ""
    feet = [dataclasses.replace(car, track_id=f"f{k}", length=14.8, width=5.9) for k in range(3)]
    assert "(not feet)?" in feet_hint(feet)


def test_a_scene_name_that_is_not_the_maps_names_the_file_and_key(tmp_path, capsys):
    """``road.scene`` of a name the map's tracks do not have, with ``traffic.library:
    [scene]``: the error names the scenario file, ``road.scene`` and the map's own scene (it
    said only "no tracks for scene"); a built-in scene extended with another map replays that
    map's scene (the built-in files no longer pin their scene)."""
    xml = Path("gridsim/data/ngsim/commonroad-xml")
    (tmp_path / "three.xml").write_bytes((xml / "USA_US101-3_3_T-1.xml").read_bytes())
    path = tmp_path / "named.yaml"
    path.write_text("name: a\nroad: {type: recorded, map: three.xml, scene: three}\n"
                    "traffic: {library: [scene]}\n")  # fmt: skip
    code, said = validate(capsys, path)
    assert code != 0 and "Traceback" not in said
    assert (
        f"{path}: road.scene 'three' (set in this file or one it extends) is not the scene "
        "of road.map three.xml ('USA_US101-3_3_T-1')" in said
    )
    other = tmp_path / "other.yaml"
    other.write_text(f"name: b\nextends: us101_3_3\nroad: {{map: {xml.resolve()}/"
                     "USA_Peach-4_8_T-1.xml}\ntraffic: {library: [scene]}\n")  # fmt: skip
    assert validate(capsys, other)[0] == 0


def test_a_road_map_that_is_no_map_names_the_scenario_the_key_and_what_it_is(tmp_path, capsys):
    """``road.map`` naming a trajectory CSV, a folder or a gzipped file: the error names the
    YAML and ``road.map`` and says what the file is (it said "not well-formed XML" of the
    CSV alone, "file not found" of a folder that is there)."""
    import gzip

    shipped = Path("gridsim/data/ngsim")
    (tmp_path / "tracks.csv").write_bytes((shipped / "ngsim_trajectories.csv").read_bytes())
    (tmp_path / "maps").mkdir()
    xml = (shipped / "commonroad-xml" / "USA_US101-3_3_T-1.xml").read_bytes()
    (tmp_path / "packed.xml").write_bytes(gzip.compress(xml))
    for target, said in (
        ("tracks.csv", "road.map: {0}/tracks.csv: not well-formed XML (syntax error: line 1, "
                       "column 0): a trajectory CSV? a map is a CommonRoad .xml file"),
        ("maps", "road.map: 'maps' is a folder (resolved to {0}/maps); it names one .xml file"),
        ("packed.xml", "road.map: {0}/packed.xml: gzip-compressed: decompress it first"),
    ):  # fmt: skip
        path = tmp_path / "s.yaml"
        path.write_text(f"name: s\nroad: {{type: recorded, map: {target}}}\n")
        code, out = validate(capsys, path)
        assert code != 0 and f"{path}: " + said.format(tmp_path) in out, out
