"""CommonRoad XML as a scenario: lanelet map and dynamic obstacles (2018 and 2020a layouts)."""

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from paths import COMMONROAD, ROOT

from gridsim.envs import ENV_ID
from gridsim.errors import DataError, ScenarioError
from gridsim.scenario.build import build_world
from gridsim.scenario.families.recorded import scene_of
from gridsim.scenario.loader import load_scenario
from gridsim.traffic.commonroad import read_tracks_commonroad, scene_id
from gridsim.traffic.library import TrajectoryLibrary

SHIPPED = ROOT / "gridsim" / "data" / "ngsim" / "commonroad-xml"
OBSTACLE = (
    '<dynamicObstacle id="5"><type>car</type><shape>{shape}</shape>'
    "<initialState><position><point><x>10</x><y>-1.75</y></point></position>"
    "<orientation><exact>0</exact></orientation><time><exact>0</exact></time>{v}"
    "</initialState><trajectory><state><position><point><x>11</x><y>-1.75</y></point>"
    "</position><orientation><exact>0</exact></orientation><time><exact>1</exact></time>{v}"
    "</state></trajectory></dynamicObstacle>"
)
RECT = "<rectangle><length>4</length><width>2</width></rectangle>"
VELOCITY = "<velocity><exact>5</exact></velocity>"


def write_xml(tmp_path, body: str, root: str = 'timeStepSize="0.1"') -> Path:
    p = tmp_path / "scene.xml"
    p.write_text(f"<commonRoad {root}>{body}</commonRoad>")
    return p


@pytest.mark.parametrize("path", sorted(SHIPPED.glob("*.xml")), ids=lambda p: p.stem)
def test_shipped_files_give_the_shipped_tracks(path):
    """Both layouts (US-101 3_3 and Lankershim are 2018b, the others 2020a) give the tracks of
    the shipped CSV, which was made from them (rounded to 1e-4)."""
    tracks = read_tracks_commonroad(path)
    expected = TrajectoryLibrary.builtin().scene(scene_id(path))
    assert [t.track_id for t in tracks] == [t.track_id for t in expected]
    for a, b in zip(tracks, expected, strict=True):
        for k in ("t", "x", "y", "heading", "speed"):
            np.testing.assert_allclose(getattr(a, k), getattr(b, k), atol=1e-4, err_msg=k)
        assert (a.length, a.width) == (b.length, b.width)
        assert a.source == str(path)


def test_both_layouts_and_time_step_sizes_agree():
    old = read_tracks_commonroad(COMMONROAD / "straight_2018b.xml")  # <obstacle>, 0.1 s
    new = read_tracks_commonroad(COMMONROAD / "straight_2020a.xml")  # <dynamicObstacle>, 0.2 s
    assert [t.track_id for t in old] == [t.track_id for t in new] == ["10", "11", "12"]
    for a, b in zip(old, new, strict=True):
        assert (a.scenario_id, b.scenario_id) == ("ZAM_Straight-1_1_T-1", "ZAM_Straight-1_2_T-1")
        np.testing.assert_allclose(b.t, a.t[::2], atol=1e-12)
        np.testing.assert_allclose(b.x, a.x[::2])
        assert b.t[-1] == pytest.approx(4.0)


def test_a_commonroad_file_is_a_scenario():
    env = gym.make(ENV_ID, scenario=str(COMMONROAD / "straight_2020a.xml"))
    seen = set()
    for seed in range(4):
        _, info = env.reset(seed=seed)
        world = env.unwrapped.world
        seen.add(world.ego_track.track_id)
        assert world.ego_track.track_id not in {t.track_id for t in world.traffic.tracks}
        assert len(world.traffic.tracks) == 2
        while True:
            _, _, terminated, truncated, info = env.step(info["reference_setpoints"])
            if terminated or truncated:
                break
        assert not info["collision"] and not info["off_road"]
    assert len(seen) > 1  # drawn from the seed


def test_keyword_overrides_and_the_same_scene_from_yaml(tmp_path):
    xml = COMMONROAD / "straight_2018b.xml"
    env = gym.make(ENV_ID, scenario=str(xml), ego={"track": "10"}, simulation={"duration": 2})
    env.reset(seed=0)
    assert env.unwrapped.world.ego_track.track_id == "10"
    assert env.unwrapped.time_limit == 2.0
    doc = {"name": "y", "road": {"type": "recorded", "map": str(xml)},
           "traffic": {"library": ["scene"]}, "ego": {"track": "10"}}  # fmt: skip
    (tmp_path / "y.yaml").write_text(yaml.safe_dump(doc))
    sc = load_scenario(tmp_path / "y.yaml")
    assert scene_of(sc) == "ZAM_Straight-1_1_T-1"
    a, b = build_world(sc, 3), build_world(load_scenario(xml, {"ego": {"track": "10"}}), 3)
    np.testing.assert_array_equal(a.ego, b.ego)


def test_scene_library_needs_a_recorded_road():
    with pytest.raises(ScenarioError, match="'scene' needs road.type recorded"):
        build_world(load_scenario("seamless", {"traffic": {"library": ["scene"]}}))


def test_obstacles_with_a_single_state_are_left_out_with_a_warning(tmp_path):
    """A dynamic obstacle with one state (or an empty trajectory) has nothing to replay: it
    is left out, now with a warning naming it, as a CSV's single-state tracks are (it was
    left out without a word: 20 tracks of 22 obstacles)."""
    from gridsim.errors import DataWarning

    single = OBSTACLE.format(shape=RECT, v=VELOCITY).replace('id="5"', 'id="9"')
    single = single[: single.index("<trajectory>")] + "<trajectory/></dynamicObstacle>"
    body = OBSTACLE.format(shape=RECT, v=VELOCITY) + single
    with pytest.warns(DataWarning, match=r"scene.xml: 1 dynamic obstacle\(s\) with a single "
                      r"state left out \(at least 2 are needed\): 9"):  # fmt: skip
        (track,) = read_tracks_commonroad(write_xml(tmp_path, body))
    assert track.track_id == "5"


def test_missing_velocity_is_derived_from_positions(tmp_path):
    (tr,) = read_tracks_commonroad(write_xml(tmp_path, OBSTACLE.format(shape=RECT, v="")))
    np.testing.assert_allclose(tr.speed, [10.0, 10.0])
    (tr,) = read_tracks_commonroad(write_xml(tmp_path, OBSTACLE.format(shape=RECT, v=VELOCITY)))
    np.testing.assert_allclose(tr.speed, [5.0, 5.0])


@pytest.mark.parametrize(
    ("body", "root", "message"),
    [
        (OBSTACLE.format(shape=RECT, v=VELOCITY), "", r"the root has no timeStepSize \(the "
         "seconds per time step"),
        (OBSTACLE.format(shape=RECT, v=VELOCITY), 'timeStepSize="0,1"',
         r"timeStepSize '0,1' is not a number \(a decimal point, not a comma\)"),
        (OBSTACLE.format(shape="<polygon/>", v=VELOCITY), 'timeStepSize="0.1"',
         "obstacle 5: <shape> must be a <rectangle> or a <circle>"),
        (OBSTACLE.format(shape=RECT, v=VELOCITY).replace("<x>11</x>", "<x>a</x>"),
         'timeStepSize="0.1"', r"obstacle 5: <state> 1 of its trajectory \(time step 1\): its "
         "<point> lacks a numeric <x>"),
        (OBSTACLE.format(shape=RECT, v=VELOCITY).replace("<orientation><exact>0</exact>"
                                                         "</orientation><time>", "<time>", 1),
         'timeStepSize="0.1"', "obstacle 5: its <initialState>: no <orientation>"),
        (OBSTACLE.format(shape=RECT, v=VELOCITY).replace("<exact>1</exact>", "<exact>0</exact>"),
         'timeStepSize="0.1"', "obstacle 5: time step 0 appears twice"),
        (OBSTACLE.format(shape=RECT, v="<velocity><exact>nan</exact></velocity>"),
         'timeStepSize="0.1"', r"track 5 of scene scene: state 0 \(t = 0 s\): speed is nan"),
        (OBSTACLE.format(shape=RECT, v=VELOCITY).replace("<x>11</x>", "<x>1e308</x>"),
         'timeStepSize="0.1"', r"track 5 .*: state 1 \(t = 0.1 s\): x = 1e\+308 m is beyond"),
        (OBSTACLE.format(shape=RECT, v=VELOCITY).replace("<x>11</x>", "<x>3000010</x>"),
         'timeStepSize="0.1"', r"state 1 \(t = 0.1 s\): jumps 3e\+06 m in 0.1 s"),
        (OBSTACLE.format(shape=RECT.replace(">4<", ">4e6<"), v=VELOCITY),
         'timeStepSize="0.1"', r"track 5 .*: length 4000000 m is outside \(0, 50\]"),
        (OBSTACLE.format(shape=RECT, v=VELOCITY) * 2,
         'timeStepSize="0.1"', "obstacle id 5 appears twice"),
        (OBSTACLE.format(shape=RECT, v=VELOCITY).replace("<exact>0</exact></time>",
                                                         "<exact>-3</exact></time>"),
         'timeStepSize="0.1"', "obstacle 5: time step -3 is negative"),
    ],
)  # fmt: skip
def test_bad_obstacles_name_the_file_and_the_obstacle(tmp_path, body, root, message):
    with pytest.raises(DataError, match=message):
        read_tracks_commonroad(write_xml(tmp_path, body, root))


def test_not_a_commonroad_file(tmp_path):
    p = tmp_path / "other.xml"
    p.write_text("<osm/>")
    with pytest.raises(DataError, match="other.xml: not a CommonRoad file"):
        read_tracks_commonroad(p)


def test_a_map_without_its_tracks_says_what_to_do(tmp_path):
    doc = {"name": "y", "road": {"type": "recorded", "map": str(COMMONROAD / "straight_2018b.xml")}}
    (tmp_path / "y.yaml").write_text(yaml.safe_dump(doc))
    with pytest.raises(DataError, match=r"no tracks for scene 'ZAM_Straight-1_1_T-1'.*"
                                        r"set traffic.library: \[scene\]"):  # fmt: skip
        build_world(load_scenario(tmp_path / "y.yaml"))


def test_import_writes_yaml_and_csv_that_give_the_same_worlds(tmp_path, capsys):
    from gridsim.cli import main

    src = tmp_path / "src"
    src.mkdir()
    for f in COMMONROAD.glob("*.xml"):
        (src / f.name).write_bytes(f.read_bytes())
    assert main(["import", str(src), "--out", str(tmp_path / "out")]) == 0
    said = capsys.readouterr().out
    out = tmp_path / "out"
    assert said.count("wrote") == 2  # each file's three outputs named (only its YAML was)
    assert (f"wrote {out / 'straight_2020a.yaml'}, {out / 'straight_2020a.csv'} and "
            f"{out / 'maps' / 'straight_2020a.xml'}") in said  # fmt: skip
    assert (out / "maps" / "straight_2020a.xml").is_file()
    doc = yaml.safe_load((out / "straight_2020a.yaml").read_text())
    assert "speed" not in doc["ego"]  # (a default recorded scenes never read)
    assert doc["traffic"]["library"] == ["straight_2020a.csv"]
    assert doc["road"]["scene"] == "ZAM_Straight-1_2_T-1"
    imported, original = (
        load_scenario(out / "straight_2020a.yaml"),
        load_scenario(src / "straight_2020a.xml"),
    )
    for seed in range(3):
        a, b = build_world(imported, seed), build_world(original, seed)
        assert a.ego_track.track_id == b.ego_track.track_id
        np.testing.assert_array_equal(a.ego, b.ego)
        for ta, tb in zip(a.traffic.tracks, b.traffic.tracks, strict=True):
            for k in ("t", "x", "y", "heading", "speed"):
                np.testing.assert_array_equal(getattr(ta, k), getattr(tb, k))
    assert main(["validate", str(out)]) == 0


def test_import_never_overwrites_and_checks_before_writing(tmp_path, capsys):
    from gridsim.cli import main

    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    (a / "scene.xml").write_bytes((COMMONROAD / "straight_2018b.xml").read_bytes())
    (b / "scene.xml").write_bytes((COMMONROAD / "straight_2020a.xml").read_bytes())
    out = tmp_path / "out"
    assert main(["import", str(a / "scene.xml"), str(b / "scene.xml"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "have the same name; their imports would overwrite each other" in err
    assert not out.exists()  # nothing written
    assert main(["import", str(a / "scene.xml"), "--out", str(out)]) == 0
    before = (out / "scene.csv").read_bytes()
    assert main(["import", str(b / "scene.xml"), "--out", str(out)]) == 2
    assert "scene.xml exists (an import never overwrites)" in capsys.readouterr().err
    assert (out / "scene.csv").read_bytes() == before
    afile = tmp_path / "file.txt"
    afile.write_text("x")
    assert main(["import", str(a / "scene.xml"), "--out", str(afile)]) == 2
    assert f"--out {afile}: is a file, expected a folder" in capsys.readouterr().err


def test_one_impossible_obstacle_is_left_out_with_a_warning(tmp_path):
    """One obstacle that jumps 3,000 km refused the whole file (as one glitch refused a CSV
    of thousands of vehicles): it is left out, the warning naming it; most of them
    impossible refuse the file, naming each."""
    import warnings

    from gridsim.errors import DataWarning

    text = (COMMONROAD / "straight_2018b.xml").read_text()
    one = tmp_path / "one.xml"
    one.write_text(text.replace("<x>25.0000</x>", "<x>3000025.0</x>", 1))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tracks = read_tracks_commonroad(one)
    (said,) = [str(w.message) for w in caught if issubclass(w.category, DataWarning)]
    assert said.startswith(f"{one}: 1 track(s) left out, their data impossible:\n    track 10 ")
    assert "jumps 3e+06 m in 0.1 s" in said and [t.track_id for t in tracks] == ["11", "12"]
    both = tmp_path / "both.xml"
    both.write_text(text.replace("<x>25.0000</x>", "<x>3000025.0</x>"))
    with pytest.raises(DataError, match=r"both.xml: 2 of its 3 tracks are impossible:\n    "
                       r"track 10 .*jumps 3e\+06 m.*\n    track 12 .*jumps"):  # fmt: skip
        read_tracks_commonroad(both)


def test_pedestrians_and_bicycles_stay_traffic_and_are_never_the_ego(tmp_path, capsys):
    """CommonRoad's obstacle ``<type>`` is read (it was not: a pedestrian was replayed as a
    car and drawn as the random ego): pedestrians and bicycles are never drawn as the ego,
    a named one is warned about, ``record`` drives them not, and a CSV keeps the kind."""
    import warnings

    from gridsim.cli import main
    from gridsim.errors import DataWarning
    from gridsim.traffic.library import read_tracks_csv, write_tracks_csv
    from neurotrajectory.data.windows import scenario_episodes

    shipped = ROOT / "gridsim" / "data" / "ngsim" / "commonroad-xml" / "USA_US101-3_3_T-1.xml"
    xml = shipped.read_text()
    first = read_tracks_commonroad(shipped)[0].track_id
    at = xml.index(f'id="{first}"')
    cut = xml.index("<type>car</type>", at)
    path = tmp_path / "walker.xml"
    path.write_text(xml[:cut] + "<type>pedestrian</type>" + xml[cut + len("<type>car</type>") :])
    tracks = read_tracks_commonroad(path)
    assert [t.kind for t in tracks].count("pedestrian") == 1 and tracks[0].kind == "pedestrian"
    assert not tracks[0].drivable_as_ego and tracks[1].drivable_as_ego
    assert main(["validate", str(path)]) == 0
    assert "1 of a pedestrian or bicycle" in capsys.readouterr().out
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        env = gym.make(ENV_ID, scenario=str(path))
        egos = set()
        for seed in range(40):
            env.reset(seed=seed)
            egos.add(env.unwrapped.world.ego_track.track_id)
    assert first not in egos and len(egos) > 3
    with pytest.warns(DataWarning, match=rf"ego.track {first} is of a pedestrian or bicycle"):
        gym.make(ENV_ID, scenario=str(path), ego={"track": first}).reset(seed=0)
    with pytest.warns(DataWarning, match=rf"1 of the .* tracks are not cars .*{first} "):
        plan, _ = scenario_episodes(str(path))
    assert all(not episode.track.endswith(f"/{first}") for episode in plan)
    written = write_tracks_csv(tracks, tmp_path / "tracks.csv")
    assert [t.kind for t in read_tracks_csv(written)] == [t.kind for t in tracks]
