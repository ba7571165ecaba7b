"""Folders and globs of scenario files are scenario collections."""

import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

from gridsim.cli import main
from gridsim.envs import ENV_ID
from gridsim.errors import ScenarioError
from gridsim.scenario.collection import load_collection, scenario_files

DATA = Path(__file__).parent / "data" / "commonroad"


@pytest.fixture
def folder(tmp_path) -> Path:
    for f in DATA.glob("*.xml"):
        shutil.copy(f, tmp_path / f.name)
    (tmp_path / "notes.txt").write_text("not a scenario")
    return tmp_path


def test_folder_and_glob_list_their_scenario_files(folder):
    names = ["straight_2018b.xml", "straight_2020a.xml"]
    assert [f.name for f in scenario_files(folder)] == names
    assert [f.name for f in scenario_files(str(folder / "*2018b.xml"))] == names[:1]
    assert scenario_files("seamless") is None
    with pytest.raises(ScenarioError, match="no scenario files"):
        scenario_files(folder / "nothing-*.yaml")


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
    with pytest.raises(ScenarioError, match="agree on sensor; .*2018b.xml differs from .*other"):
        load_collection(folder)


def test_validate_and_scenarios_print_one_line_per_file(folder, capsys):
    assert main(["scenarios", str(folder)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2 and out[0].startswith(str(folder / "straight_2018b.xml"))
    assert main(["validate", str(folder)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[-1] == "2 of 2 scenario files OK" and len(out) == 3
    (folder / "broken.yaml").write_text("name: x\nroad: {type: recorded}\n")
    assert main(["validate", str(folder)]) == 2
    out = capsys.readouterr().out
    assert f"{folder / 'broken.yaml'}: 2 problem(s)" in out
    assert "road.map: Field required" in out and "2 of 3 scenario files OK" in out


def test_record_a_folder_as_a_named_group(folder, tmp_path):
    from neurotrajectory.cli import main as nt_main
    from neurotrajectory.compare.evaluation import EvalConfig
    from neurotrajectory.data.windows import DatasetError, group_scenarios, load_dataset

    assert group_scenarios("urban") == ("lankershim_1_1", "peachtree_4_8")
    assert len(group_scenarios("mine", str(folder))) == 2
    out = tmp_path / "ds"
    code = nt_main(["record", "--scenario", str(folder), "--group", "mine", "--out", str(out),
                    "--stride", "5", "--quiet"])  # fmt: skip
    assert code == 0
    ds = load_dataset(out)
    assert ds.manifest["group"] == "mine"
    assert len(set(ds.windows.track.tolist())) == 6  # 3 tracks in each file, each the ego once
    EvalConfig(groups=("mine",), sources={"mine": str(folder)})
    with pytest.raises(DatasetError, match="unknown scenario groups"):
        EvalConfig(groups=("mine",))
