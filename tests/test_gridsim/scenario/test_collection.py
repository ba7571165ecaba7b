"""Folders and globs of scenario files are scenario collections."""

import re
import shutil
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from paths import COMMONROAD

from gridsim.cli import main
from gridsim.envs import ENV_ID
from gridsim.errors import DataWarning, ScenarioError
from gridsim.scenario.collection import load_collection, scenario_files, skipped_lines


@pytest.fixture
def folder(tmp_path) -> Path:
    for f in COMMONROAD.glob("*.xml"):
        shutil.copy(f, tmp_path / f.name)
    (tmp_path / "notes.txt").write_text("not a scenario")
    return tmp_path


def test_folder_and_glob_list_their_scenario_files(folder):
    names = ["straight_2018b.xml", "straight_2020a.xml"]
    assert [f.name for f in scenario_files(folder)] == names
    assert [f.name for f in scenario_files(str(folder / "*2018b.xml"))] == names[:1]
    assert scenario_files("seamless") is None
    with pytest.raises(ScenarioError, match=r"no scenario files .* match the pattern"):
        scenario_files(folder / "nothing-*.yaml")
    (folder / "empty").mkdir()
    with pytest.raises(ScenarioError, match=r"no scenario files .* in it"):
        scenario_files(folder / "empty")


def test_links_name_each_file_once_and_a_broken_link_is_said(folder, capsys):
    """A '**' glob through a link to a folder above listed every file once per level (84
    copies of a dataset were recorded); two links to one file counted it twice; a broken link
    (an unmounted share) was left out without a word. Each file is listed once, by its
    shortest name, saying how many names were left out; a broken link is listed, and loading
    it says where it points."""
    (folder / "loop").symlink_to(folder)
    (folder / "again.xml").symlink_to(folder / "straight_2018b.xml")
    (folder / "broken.xml").symlink_to(folder / "unmounted" / "scene.xml")
    with pytest.warns(DataWarning, match=r"of its paths name files listed already"):
        files = scenario_files(str(folder / "**" / "*.xml"))
    assert [f.relative_to(folder).as_posix() for f in files] == [
        "broken.xml", "straight_2018b.xml", "straight_2020a.xml"]  # fmt: skip
    assert main(["scenarios", str(folder)]) == 1
    out = capsys.readouterr().out
    assert "broken.xml: does not load: scenario file not found" in out
    assert str(folder / "unmounted" / "scene.xml") in out
    from gridsim.errors import not_there  # a folder on the way that is a broken link: named

    (folder / "share").symlink_to("../nowhere")  # (relative: said from the link's folder)
    assert not_there(folder / "share" / "t.csv") == (
        f"{folder / 'share' / 't.csv'} (in {folder / 'share'}, a link to "
        f"{folder.parent / 'nowhere'}, which is not there)")  # fmt: skip


def test_a_comma_separated_list_is_a_collection_in_its_order(folder):
    """Built-in names, files and globs mix in a list; an empty or repeated item is refused."""
    xml = folder / "straight_2020a.xml"
    files = scenario_files(f"us101_4_1, {xml},us101_3_3")
    assert files == [Path("us101_4_1"), xml, Path("us101_3_3")]
    assert scenario_files(f"{folder / '*2018b.xml'},seamless") == [
        folder / "straight_2018b.xml", Path("seamless")]  # fmt: skip
    with pytest.raises(ScenarioError, match="an empty item"):
        scenario_files("us101_4_1,")
    with pytest.raises(ScenarioError, match="us101_4_1 listed more than once"):
        scenario_files("us101_4_1,us101_4_1")
    env = gym.make(ENV_ID, scenario="us101_4_1,us101_3_3")
    drawn = set()
    for seed in range(12):
        env.reset(seed=seed)
        drawn.add(env.unwrapped.scenario.name)
    assert drawn == {"us101_4_1", "us101_3_3"}


def test_ego_track_names_tracks_of_a_collections_scenes_by_scene(folder):
    """``SCENE/ID`` names in ego.track: each scene of a collection drives only its own; a
    scene that the list names no track of is skipped, saying so."""
    from gridsim.scenario.families.recorded import scene_of

    a, b = (scene_of(load_collection(name)[0]) for name in ("us101_4_1", "us101_3_3"))
    listed = [f"{a}/394", f"{a}/468", f"{b}/400"]
    env = gym.make(ENV_ID, scenario="us101_4_1,us101_3_3", ego={"track": listed})
    driven = set()
    for seed in range(16):
        env.reset(seed=seed)
        driven.add(f"{scene_of(env.unwrapped.scenario)}/{env.unwrapped.world.ego_track.track_id}")
    assert driven == set(listed)
    with pytest.warns(DataWarning, match=f"names no track of scene '{b}', only of other scenes"):
        only_a = load_collection("us101_4_1,us101_3_3", {"ego": {"track": listed[:2]}})
    assert [sc.name for sc in only_a] == ["us101_4_1"]
    one = gym.make(ENV_ID, scenario="us101_3_3", ego={"track": [f"{b}/9999", f"{b}/400"]})
    with pytest.raises(ScenarioError, match="ego.track lists 1 track.* not in scene .*: 9999"):
        one.reset(seed=0)


def test_an_environment_draws_a_scene_per_reset_from_the_seed(folder):
    env = gym.make(ENV_ID, scenario=str(folder))
    drawn = []
    for seed in range(8):
        env.reset(seed=seed)
        drawn.append((env.unwrapped.scenario.name, env.unwrapped.world.ego[:2].copy()))
    assert {name for name, _ in drawn} == {"straight_2018b", "straight_2020a"}
    again = gym.make(ENV_ID, scenario=str(folder))
    for seed in (3, 5):
        again.reset(seed=seed)
        assert again.unwrapped.scenario.name == drawn[seed][0]
        np.testing.assert_array_equal(again.unwrapped.world.ego[:2], drawn[seed][1])


def test_a_collection_must_share_spaces(folder):
    doc = {"name": "other", "road": {"type": "seamless"}, "sensor": {"rows": 64}}
    (folder / "other.yaml").write_text(yaml.safe_dump(doc))
    with pytest.raises(
        ScenarioError, match="agree on sensor; .*2018b.xml has sensor.rows = 128, .*other.yaml 64"
    ):
        load_collection(folder)


def test_validate_refuses_files_that_cannot_run_together_and_scenarios_lists_them(folder, capsys):
    doc = {"name": "other", "road": {"type": "seamless"}, "sensor": {"rows": 64}}
    (folder / "other.yaml").write_text(yaml.safe_dump(doc))
    assert main(["validate", str(folder)]) == 2
    out = capsys.readouterr().out.splitlines()
    assert out[-2] == "3 of 3 scenario files OK"  # each alone
    assert "must agree on sensor; " in out[-1] and "sensor.rows = 128" in out[-1]
    assert main(["scenarios", str(folder)]) == 0
    assert len(capsys.readouterr().out.splitlines()) == 3


def test_validate_and_scenarios_print_one_line_per_file(folder, capsys):
    assert main(["scenarios", str(folder)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2 and out[0].startswith(str(folder / "straight_2018b.xml"))
    assert "(recorded, scene " in out[0]  # the id ego.track's SCENE/ID names
    assert main(["validate", str(folder)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[-1] == "2 of 2 scenario files OK" and len(out) == 3
    (folder / "broken.yaml").write_text("name: x\nroad: {type: recorded}\n")
    assert main(["validate", str(folder)]) == 2
    out = capsys.readouterr().out
    assert f"{folder / 'broken.yaml'}: invalid scenario (1 problem):" in out
    assert "road.map is missing; it is required" in out and "2 of 3 scenario files OK" in out
    bad = {"name": "bad", "road": {"type": "seamless"}, "sensor": {"rows": -3, "colour": 1}}
    (folder / "bad.yaml").write_text(yaml.safe_dump(bad))
    assert main(["validate", str(folder)]) == 2
    out = capsys.readouterr().out.splitlines()
    at = out.index(f"{folder / 'bad.yaml'}: invalid scenario (2 problems):")
    assert out[at + 1].startswith("  - sensor.") and out[at + 2].startswith("  - sensor.")
    assert out[-1] == "2 of 4 scenario files OK"


def test_record_a_folder_as_a_named_group(folder, tmp_path):
    from neurotrajectory.cli import main as nt_main
    from neurotrajectory.compare.evaluation import EvalConfig
    from neurotrajectory.data.storage import load_dataset
    from neurotrajectory.data.windows import DatasetError, group_scenarios

    assert group_scenarios("urban") == ("lankershim_1_1", "peachtree_4_8")
    assert len(group_scenarios("mine", str(folder))) == 2
    out = tmp_path / "ds"
    code = nt_main(["record", "--scenario", str(folder), "--name", "mine", "--out", str(out),
                    "--stride", "5", "--quiet"])  # fmt: skip
    assert code == 0
    ds = load_dataset(out)
    assert ds.manifest["group"] == "mine"
    assert len(set(ds.windows.track.tolist())) == 6  # 3 tracks in each file, each the ego once
    EvalConfig(groups=("mine",), sources={"mine": str(folder)})
    with pytest.raises(DatasetError, match="unknown scenario groups"):
        EvalConfig(groups=("mine",))


def add_unusable_files(folder: Path) -> dict[str, str]:
    """Files a real collection holds next to good ones, and the reason each is skipped."""
    text = (COMMONROAD / "straight_2018b.xml").read_text()
    # jumps of 3,000 km in two of its three vehicles (one alone is left out, with a warning)
    glitch = text.replace("<x>25.0000</x>", "<x>3000025.0</x>")
    (folder / "glitch.xml").write_text(glitch.replace("Straight-1_1", "Glitch-1_1"))
    (folder / "truncated.xml").write_text(text[: len(text) // 2])
    head, _, _ = text.partition("<obstacle")
    (folder / "no_tracks.xml").write_text(head.replace("Straight-1_1", "Empty-1_1")
                                          + "</commonRoad>\n")  # fmt: skip
    return {
        "glitch.xml": "2 of its 3 tracks are impossible",
        "truncated.xml": "not well-formed XML",
        "no_tracks.xml": "no vehicle tracks",
    }


def test_validate_and_scenarios_take_the_files_of_a_glob_the_shell_expanded(folder, capsys):
    """`gridsim validate col/*.xml` unquoted gives several paths (it was refused as
    'unrecognized arguments'): they are checked as a list of scenario files."""
    files = [str(f) for f in sorted(folder.glob("*.xml"))]
    assert main(["validate", *files]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[-1] == "2 of 2 scenario files OK"
    assert main(["scenarios", *files]) == 0
    assert [line.split(":")[0] for line in capsys.readouterr().out.splitlines()] == files


def test_scenarios_lists_a_folder_without_reading_its_recordings(folder, capsys):
    """A listing reads the scenario files, not their maps and recordings (a folder of large
    CSVs took a minute): a file whose data is unsound is listed, and validate names it."""
    add_unusable_files(folder)
    assert main(["scenarios", str(folder)]) == 0
    out = capsys.readouterr()
    assert [line.split(":")[0] for line in out.out.splitlines()] == [
        str(folder / name) for name in ("glitch.xml", "no_tracks.xml", "straight_2018b.xml",
                                        "straight_2020a.xml", "truncated.xml")]  # fmt: skip
    assert f"`gridsim validate {folder}` reads their maps and recordings" in out.err
    assert main(["validate", str(folder)]) == 2
    assert "jumps 3e+06 m in 0.1 s" in capsys.readouterr().out


def test_unusable_files_of_a_collection_are_skipped_and_named(folder):
    reasons = add_unusable_files(folder)
    with pytest.warns(DataWarning) as caught:
        env = gym.make(ENV_ID, scenario=str(folder))
    (message,) = [
        str(w.message)
        for w in caught
        if issubclass(w.category, DataWarning) and "skipped" in str(w.message)
    ]
    assert message.startswith(f"{folder}: skipped 3 of 5 scenario files that cannot be used:")
    for name, reason in reasons.items():
        line = next(s for s in message.splitlines() if f"{folder / name}: " in s)
        assert reason in line, line
    names = {sc.name for sc in env.unwrapped.scenarios}
    assert names == {"straight_2018b", "straight_2020a"}
    for seed in range(6):
        env.reset(seed=seed)
        assert env.unwrapped.scenario.name in names


def test_record_refuses_a_folder_that_run_refuses(folder, tmp_path, capsys):
    """Files that disagree on what a dataset holds once (the grid, the ego) are not recorded
    into one dataset: the same refusal, naming the key and both values, as a run's."""
    from neurotrajectory.cli import main as nt_main

    doc = {"name": "other", "road": {"type": "seamless"}, "sensor": {"rows": 64}}
    (folder / "other.yaml").write_text(yaml.safe_dump(doc))
    code = nt_main(["record", "--scenario", str(folder), "--out", str(tmp_path / "ds"),
                    "--quiet"])  # fmt: skip
    assert code == 2 and not (tmp_path / "ds").exists()
    assert "must agree on sensor; " in capsys.readouterr().err


def test_a_dataset_s_manifest_lists_the_files_that_did_not_load(folder, tmp_path, capsys):
    from neurotrajectory.cli import main as nt_main
    from neurotrajectory.data.storage import load_dataset

    (folder / "truncated.xml").write_text((folder / "straight_2018b.xml").read_text()[:500])
    code = nt_main(["record", "--scenario", str(folder), "--out", str(tmp_path / "ds"),
                    "--stride", "5", "--quiet"])  # fmt: skip
    assert code == 0 and "truncated.xml" in capsys.readouterr().err  # warned once, too
    (skipped,) = load_dataset(tmp_path / "ds").manifest["skipped"]
    assert skipped["file"] == str(folder / "truncated.xml")
    assert "XML" in skipped["reason"]


def test_a_yaml_file_with_mistakes_refuses_the_collection_naming_every_problem(folder):
    """A scenario file of a collection that does not load is its author's mistake (a key
    misspelt, a value out of range), not data to skip: skipping it dropped the scenario from
    training with a warning only. The refusal shows every problem of the file."""
    doc = {"name": "bad", "road": {"type": "seamless"}, "sensor": {"rows": -3, "colour": 1}}
    (folder / "bad.yaml").write_text(yaml.safe_dump(doc))
    with pytest.raises(ScenarioError, match="1 scenario file of the collection does not load"
                       ) as refused:  # fmt: skip
        gym.make(ENV_ID, scenario=str(folder))
    shown = str(refused.value).split(f"{folder / 'bad.yaml'}: ", 1)[1]
    assert "sensor.rows" in shown and "-3" in shown and "sensor.colour" in shown, shown
    many = [(Path("f.yaml"), "\n".join(f"problem {k}" for k in range(10)))]
    lines = skipped_lines(many).splitlines()
    assert lines[0] == "  - f.yaml: problem 0" and lines[5] == "      problem 5"
    assert lines[-1] == "      (+4 more lines: gridsim validate f.yaml)"


def test_a_collection_with_no_usable_file_names_them_all(tmp_path):
    reasons = add_unusable_files(tmp_path)
    with pytest.raises(ScenarioError, match="none of its 3 scenario files can be used") as err:
        gym.make(ENV_ID, scenario=str(tmp_path))
    for name, reason in reasons.items():
        assert f"{tmp_path / name}: " in str(err.value) and reason in str(err.value)


def test_record_skips_the_unusable_files_and_says_so(folder, tmp_path, capsys):
    from neurotrajectory.cli import main as nt_main
    from neurotrajectory.data.storage import load_dataset

    add_unusable_files(folder)
    out = tmp_path / "ds"
    code = nt_main(["record", "--scenario", str(folder), "--name", "mine", "--out", str(out),
                    "--stride", "5", "--quiet"])  # fmt: skip
    assert code == 0
    err = capsys.readouterr().err
    assert "warning: " in err and "skipped 3 of 5 scenario files" in err
    assert "glitch.xml" in err and "Traceback" not in err
    assert len(set(load_dataset(out).windows.track.tolist())) == 6


def test_keys_that_the_road_type_does_not_use_are_named():
    """A track on a generated road, synthetic traffic on a recorded scene: said, not run on
    quietly; a resolved scenario, which states every key at its default, says nothing."""
    from gridsim.scenario.loader import load_scenario

    with pytest.warns(DataWarning, match=r"ego.track not used by road type 'seamless' \(only "):
        load_scenario("seamless", {"ego": {"track": "5"}})
    with pytest.warns(DataWarning, match=r"traffic.participants not used by road type 'recorded'"):
        load_scenario("us101_4_1", {"traffic": {"participants": 50}})
    # each family's own: the recorded ego starts as its track, the city ego on a route
    said = (
        r"traffic.v_max, ego.speed not used by road type 'recorded' \(recorded scenes "
        r"take their traffic, lanes and the ego's start from the recording\)"
    )
    with pytest.warns(DataWarning, match=said):
        load_scenario("us101_4_1", {"ego": {"speed": 20}, "traffic": {"v_max": 30}})
    lane = r"ego.lane not used by road type 'inner_city' \(the ego starts on a route of the "
    with pytest.warns(DataWarning, match=lane + r"street network\); ignored$"):  # (not: tracks)
        load_scenario("inner_city", {"ego": {"lane": 0}})
    with pytest.warns(DataWarning, match=r"ego.track not used .* have tracks\); ego.lane not"):
        load_scenario("inner_city", {"ego": {"lane": 0, "track": "5"}})
    # a key inside a block: the recorded ego takes its track's size (its wheelbase is read)
    size = r"ego.vehicle.length, ego.vehicle.width not used by road type 'recorded' \(the ego "
    with pytest.warns(DataWarning, match=size + r"takes the size of the track it drives\)"):
        load_scenario("us101_4_1", {"ego": {"vehicle": {"length": 12, "width": 3,
                                                          "wheelbase": 2.5}}})  # fmt: skip
    # a wheelbase shortened to 0.7 x the length is said (on a generated road: the car's own)
    with pytest.warns(
        DataWarning,
        match=r"wheelbase 4 m is more than 0.7 x ego.vehicle.length "
        r"4.5 m: the car is driven with a wheelbase of 3.15 m",
    ):
        load_scenario("seamless", {"ego": {"vehicle": {"length": 4.5, "wheelbase": 4.0}}})
    # an episode that lasts past simulation.duration, to the end of its decision, is said
    with pytest.warns(
        DataWarning,
        match=r"simulation.duration 10 s is not a whole number of "
        r"decisions \(env.decision_period 0.3 s\): an episode "
        r"ends after its decision 34, at 10.2 s",
    ):
        load_scenario("seamless", {"env": {"decision_period": 0.3}, "simulation": {"duration": 10}})
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        for name in ("seamless", "inner_city", "us101_4_1"):
            resolved = load_scenario(name).config.model_dump(mode="json")
            load_scenario(name, {k: resolved[k] for k in ("ego", "traffic")})


def test_a_collection_override_read_by_some_members_only_is_not_warned_about(tmp_path):
    """``train`` hands a collection's training tracks (``ego.track``) to every member: its
    generated scene does not read them, and says nothing; the same key in that scene's own
    file is still named."""
    import warnings

    from gridsim.scenario.collection import load_collection

    shared = "ego: {vehicle: {v_max: 25.0, a_max: 3.0}}\nenv: {speed_range: [0.0, 30.0]}\n"
    seamless = tmp_path / "seamless_highway.yaml"
    seamless.write_text("name: seamless_highway\nroad: {type: seamless}\n" + shared)
    mixed = f"us101_4_1,{seamless}"
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        scenarios = load_collection(mixed, {"ego": {"track": ["USA_US101-4_1_T-1/399"]}})
    assert [sc.config.road.type for sc in scenarios] == ["recorded", "seamless"]
    seamless.write_text(
        "name: seamless_highway\nroad: {type: seamless}\n"
        + shared.replace("{vehicle", "{track: '5', vehicle")
    )
    with pytest.warns(DataWarning, match=r"seamless_highway.yaml: ego.track not used by road"):
        load_collection(mixed, {"ego": {"track": ["USA_US101-4_1_T-1/399"]}})


def test_a_folder_says_its_subfolders_are_not_read(tmp_path):
    """Scenario files in a subfolder are not read: a warning says so and gives the glob
    that reads them all (they were left out silently)."""
    from importlib import resources

    from gridsim.errors import DataWarning
    from gridsim.scenario.collection import scenario_files

    (tmp_path / "sub").mkdir()
    (tmp_path / "maps").mkdir()  # `gridsim import` puts the maps there: not scenario files
    (tmp_path / "maps" / "USA_US101-4_1_T-1.xml").write_text("<commonRoad/>")
    for name, where in (("us101_4_1", tmp_path), ("us101_3_3", tmp_path / "sub")):
        text = resources.files("gridsim").joinpath("data", "scenarios", f"{name}.yaml")
        (where / f"{name}.yaml").write_text(text.read_text())
    with pytest.warns(DataWarning, match=r"its subfolders sub hold scenario files that are not"
                      r".* give the glob '.*\*\*/\*\.yaml'\)$"):  # fmt: skip
        assert scenario_files(tmp_path) == [tmp_path / "us101_4_1.yaml"]
    assert len(scenario_files(str(tmp_path / "**" / "*.yaml"))) == 2


def test_an_empty_trajectory_file_is_called_empty(tmp_path):
    from gridsim.errors import DataError
    from gridsim.traffic.library import read_tracks_csv

    (tmp_path / "t.csv").write_text("")
    with pytest.raises(DataError, match=r"t.csv: the file is empty; a trajectory CSV starts"):
        read_tracks_csv(tmp_path / "t.csv")


def test_a_recording_copied_under_another_name_is_named(tmp_path, capsys):
    """Two files of a folder replaying the same recording (a CSV saved again with a BOM)
    would count its episodes and windows twice: loading the folder warns, validate says so;
    the same scene with other ego tracks is not a copy."""
    from importlib import resources

    from gridsim.scenario.collection import usable_files

    (tmp_path / "a").mkdir()
    text = resources.files("gridsim").joinpath("data", "scenarios", "us101_3_3.yaml").read_text()
    (tmp_path / "a" / "one.yaml").write_text(text)
    (tmp_path / "a" / "two.yaml").write_text(text.replace("name: us101_3_3", "name: again"))
    with pytest.warns(DataWarning, match=r"two.yaml replays the same recording as .*one.yaml"):
        usable_files(tmp_path / "a")
    assert main(["validate", str(tmp_path / "a")]) == 0
    assert "two.yaml replays the same recording as" in capsys.readouterr().out
    (tmp_path / "a" / "two.yaml").write_text(text + "ego:\n  track: ['363', '376']\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        usable_files(tmp_path / "a")


def test_other_recordings_of_a_scene_with_the_same_track_ids_are_named(tmp_path, capsys):
    """Two days recorded on one map whose vehicle ids restart: the same SCENE/ID names for
    other vehicles (windows, splits and --track would mix them up). A copy of one recording
    is the other warning's (it replays the same recording)."""
    import csv
    from importlib import resources

    from gridsim.cli import main as gridsim_main
    from gridsim.scenario.collection import load_collection

    source = resources.files("gridsim").joinpath("data", "ngsim", "ngsim_trajectories.csv")
    rows = [r for r in csv.DictReader(source.read_text().splitlines())
            if r["scenario_id"] == "USA_US101-3_3_T-1"]  # fmt: skip
    for day, shift in (("day1", 0.0), ("day2", 0.4)):
        with (tmp_path / f"{day}.csv").open("w", newline="") as fh:
            out = csv.DictWriter(fh, fieldnames=list(rows[0]))
            out.writeheader()
            out.writerows({**r, "x_m": f"{float(r['x_m']) + shift:.4f}"} for r in rows)
        (tmp_path / f"{day}.yaml").write_text(
            f"name: {day}\nroad: {{type: recorded, map: 'builtin:USA_US101-3_3_T-1'}}\n"
            f"traffic: {{library: [{day}.csv]}}\n")  # fmt: skip
    said = r"day2.yaml and .*day1.yaml are other recordings of scene USA_US101-3_3_T-1 with 12 "
    with pytest.warns(
        DataWarning, match=said + r"track id\(s\) in common \(363, 376, 387, 388, 394 "
    ):
        load_collection(tmp_path)
    assert gridsim_main(["validate", str(tmp_path)]) == 0
    assert "track id(s) in common" in capsys.readouterr().out
    # a copy with one sample moved 3 m (a glitch) is another recording, not the same one
    lines = (tmp_path / "day1.csv").read_text().splitlines()
    head, first = lines[0].split(","), lines[5].split(",")
    first[head.index("x_m")] = f"{float(first[head.index('x_m')]) + 3.0:.4f}"
    (tmp_path / "day2.csv").write_text("\n".join([*lines[:5], ",".join(first), *lines[6:]]))
    with pytest.warns(DataWarning, match=r"with 1 track id\(s\) in common") as seen:
        load_collection(tmp_path)
    assert not any("replays the same recording" in str(w.message) for w in seen)
    # a folder of many days of one site: said once (it was said for every file)
    for day in ("day3", "day4"):
        (tmp_path / f"{day}.csv").write_text((tmp_path / "day2.csv").read_text())
        (tmp_path / f"{day}.yaml").write_text(
            (tmp_path / "day2.yaml").read_text().replace("day2", day))  # fmt: skip
    with pytest.warns(DataWarning) as seen:
        load_collection(tmp_path)
    shared = [str(w.message) for w in seen if "other recordings of scene" in str(w.message)]
    assert len(shared) == 1
    assert re.search(r"3 files \(.*day2.yaml, .*day3.yaml, .*day4.yaml\) are other recordings "
                     r"of scene USA_US101-3_3_T-1 than .*day1.yaml, each with track ids in "
                     r"common with it \(up to 1: ", shared[0])  # fmt: skip
    assert gridsim_main(["validate", str(tmp_path)]) == 0
    assert capsys.readouterr().out.count("other recordings of scene") == 1


def test_a_data_warning_points_at_the_users_line(tmp_path):
    """``gym.make`` of a scenario with a key its road type does not read: the warning's
    place is the user's call, not a line of the loader (where Python's default filter would
    also have shown it once for every user line together)."""
    import warnings

    import gymnasium as gym

    path = tmp_path / "mine.yaml"
    path.write_text("name: mine\nroad: {type: seamless}\nego: {track: '5'}\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        gym.make("GridSim-v0", scenario=str(path))  # the line the warning names
    (said,) = [w for w in caught if issubclass(w.category, DataWarning)]
    assert said.filename == __file__ and "ego.track not used" in str(said.message)


def test_an_ego_track_of_no_scene_is_refused_one_of_another_scene_kept(tmp_path):
    """A collection's scenes share one ego.track list, so a SCENE/ID of another of its scenes
    is kept; a SCENE/ID of no scene (a misspelt scene: 'USA_US101-3_3/363') was dropped
    without a word, and is refused, alone or in a collection, by the env and by validate."""
    from gridsim.cli import main

    head = "road: {type: recorded, map: builtin:USA_US101-3_3_T-1}\n"
    typo = tmp_path / "typo.yaml"
    typo.write_text("name: t\n" + head + 'ego: {track: [USA_US101-3_3/363, "376"]}\n')
    said = r"ego.track names 1 track of no scene here: USA_US101-3_3/363; the scene\(s\): USA_US1"
    with pytest.raises(ScenarioError, match=said):
        gym.make(ENV_ID, scenario=str(typo))
    assert main(["validate", str(typo)]) == 2
    shared = ' ego: {track: ["USA_US101-3_3_T-1/363", "USA_US101-4_1_T-1/381"]}\n'
    (tmp_path / "both").mkdir()
    (tmp_path / "both" / "a.yaml").write_text("name: a\n" + head + shared.strip() + "\n")
    (tmp_path / "both" / "b.yaml").write_text(
        "name: b\nroad: {type: recorded, map: builtin:USA_US101-4_1_T-1}\n" + shared.strip() + "\n"
    )
    env = gym.make(ENV_ID, scenario=str(tmp_path / "both"))  # not refused
    assert [sc.name for sc in env.unwrapped.scenarios] == ["a", "b"]


def test_a_yaml_mistake_found_building_the_world_refuses_too_data_problems_are_skipped(folder):
    """A library file not found or an ego track not in the scene (raised while the world is
    built) are the author's mistakes as much as a misspelt key; a misspelt built-in name in a
    list too ('seamless,nosuch' trained on seamless alone). A recorded scene with no track to
    drive is its data's: skipped, as before."""
    (folder / "lib.yaml").write_text("name: lib\nroad: {type: seamless}\n"
                                     "traffic: {library: nosuch.csv}\n")  # fmt: skip
    with pytest.raises(ScenarioError, match=r"lib.yaml: traffic.library: file not found"):
        gym.make(ENV_ID, scenario=str(folder))
    (folder / "lib.yaml").unlink()
    with pytest.raises(ScenarioError, match=r"nosuch: unknown scenario 'nosuch'"):
        load_collection("seamless,nosuch")
    add_unusable_files(folder)  # no_tracks.xml and others: data, skipped
    with pytest.warns(DataWarning, match="skipped 3 of 5"):
        gym.make(ENV_ID, scenario=str(folder))


def test_a_track_of_a_skipped_file_s_scene_is_warned_about_not_refused(folder):
    """A collection whose file of scene X was skipped (its data) may name X's tracks: the
    refusal of a scene that is nowhere would stop a run over one bad file."""
    (folder / "truncated.xml").write_text((COMMONROAD / "straight_2018b.xml").read_text()[:500])
    (folder / "mine.yaml").write_text(
        "name: mine\nroad: {type: recorded, map: builtin:USA_US101-4_1_T-1}\n"
        'ego: {track: ["USA_US101-4_1_T-1/381", "Gone-1_1/3"]}\n')  # fmt: skip
    with pytest.warns(DataWarning, match=r"Gone-1_1/3.*may be of a skipped file's scene"):
        load_collection(str(folder), {"ego": {"vehicle": {"v_max": 25.0}}})


def test_a_map_beside_the_yaml_that_names_it_is_not_a_scenario_of_its_own(tmp_path):
    """The layout the docs show (``map: scene.xml`` beside the YAML file) made a folder of
    one scene a collection of two: the XML was read as a scenario too, and its windows and
    episodes counted twice. A file a YAML names as its map or library is its data; an XML
    file no YAML names is still a scenario."""
    shutil.copy(COMMONROAD / "straight_2020a.xml", tmp_path / "scene.xml")
    shutil.copy(COMMONROAD / "straight_2018b.xml", tmp_path / "other.xml")
    (tmp_path / "mine.yaml").write_text(
        "name: mine\nroad: {type: recorded, map: scene.xml}\ntraffic: {library: [scene]}\n"
    )
    assert scenario_files(tmp_path) == [tmp_path / "mine.yaml", tmp_path / "other.xml"]
    assert scenario_files(str(tmp_path / "*")) == [tmp_path / "mine.yaml", tmp_path / "other.xml"]
    scenarios = load_collection(tmp_path)
    assert sorted(s.name for s in scenarios) == ["mine", "other"]


def test_a_folder_listing_reads_its_yaml_files_within_the_loaders_bounds(tmp_path):
    """The listing looks into each YAML file for the map it names, with the loader's own
    reading (its bounds): a file nested thousands of brackets deep is refused at once
    (YAML's own reader raised a RecursionError out of the listing) and still listed
    (loading it says why)."""
    from gridsim.scenario.loader import load_scenario

    shutil.copy(COMMONROAD / "straight_2020a.xml", tmp_path / "scene.xml")
    (tmp_path / "deep.yaml").write_text("road: " + "[" * 3000 + "]" * 3000 + "\n")
    assert scenario_files(tmp_path) == [tmp_path / "deep.yaml", tmp_path / "scene.xml"]
    with pytest.raises(ScenarioError, match="brackets nested 3000 levels deep"):
        load_scenario(tmp_path / "deep.yaml")


def test_scenarios_lists_a_folder_with_a_file_that_does_not_load(folder, capsys):
    """One misspelt key in one file of a folder listed nothing (the error alone): the other
    files are listed, the broken one with its first problem, and the status is 1."""
    (folder / "typo.yaml").write_text("extends: seamless\nname: typo\ntraffic:\n  participant: 5\n")
    assert main(["scenarios", str(folder)]) == 1
    out = capsys.readouterr()
    lines = out.out.splitlines()
    assert len(lines) == 3 and lines[0].startswith(str(folder / "straight_2018b.xml"))
    assert lines[2] == (f"{folder / 'typo.yaml'}: does not load: invalid scenario (1 problem): "
                        "traffic.participant: unknown key (did you mean "
                        "'traffic.participants'?) (got 5)")  # fmt: skip
    assert "2 scenarios listed, 1 file that does not load" in out.err
    assert main(["scenarios", str(folder / "typo.yaml")]) == 2  # one file: its error
