"""Scenario families as registry entries: a family registered from outside the package (a
toy one here) is read from YAML with its defaults, built and driven end to end, and leaves
no trace when removed."""

from typing import Literal

import gymnasium as gym
import numpy as np
import pytest
import yaml

import gridsim  # noqa: F401  (registers GridSim-v0)
from gridsim.errors import ScenarioError
from gridsim.road.seamless import SeamlessRoad
from gridsim.scenario.families import seamless
from gridsim.scenario.family import FAMILIES, Family, register_family, unregister_family
from gridsim.scenario.loader import load_scenario


class ToyRoadConfig(seamless.SeamlessRoadConfig):
    """A toy family: a seamless road under another tag, with defaults of its own."""

    type: Literal["toy_road"]


def _build(scenario, seed):
    return seamless.build(scenario, seed)


TOY = Family(ToyRoadConfig, _build, defaults={"traffic": {"participants": 3}, "ego": {"lane": 0}})


@pytest.fixture
def toy_family():
    register_family(TOY)
    yield TOY
    unregister_family(TOY.tag)


def _toy_yaml(tmp_path, **road):
    path = tmp_path / "toy.yaml"
    doc = {"name": "toy", "road": {"type": "toy_road", **road}, "simulation": {"duration": 3.0}}
    path.write_text(yaml.safe_dump(doc))
    return path


def test_a_registered_family_loads_with_its_defaults_and_drives(toy_family, tmp_path):
    path = _toy_yaml(tmp_path, lanes=2)
    sc = load_scenario(path)
    assert isinstance(sc.config.road, ToyRoadConfig) and sc.config.road.lanes == 2
    assert sc.config.traffic.participants == 3 and sc.config.ego.lane == 0  # its defaults
    env = gym.make("GridSim-v0", scenario=str(path))
    obs, info = env.reset(seed=4)
    assert isinstance(env.unwrapped.world.road, SeamlessRoad)
    steps = 0
    for _ in range(10):
        obs, reward, terminated, truncated, info = env.step(info["reference_setpoints"])
        steps += 1
        assert np.isfinite(reward).all()
        if terminated or truncated:
            break
    assert steps == 10 and not info["collision"] and not info["off_road"]
    env.close()


def test_a_family_config_is_checked_like_the_built_in_ones(toy_family, tmp_path):
    with pytest.raises(ScenarioError, match=r"road\.lanes"):
        load_scenario(_toy_yaml(tmp_path, lanes=99))


def test_registration_refuses_a_taken_tag_and_removal_leaves_no_trace(tmp_path):
    with pytest.raises(ScenarioError, match="'seamless' is registered already"):
        register_family(Family(seamless.SeamlessRoadConfig, _build))
    register_family(TOY)
    unregister_family(TOY.tag)
    assert TOY.tag not in FAMILIES
    with pytest.raises(ScenarioError, match="road.type 'toy_road' is no scenario family; the "
                       "families: inner_city, recorded, seamless"):  # fmt: skip
        load_scenario(_toy_yaml(tmp_path))
    assert load_scenario("seamless").config.road.type == "seamless"  # the others unharmed


def test_a_family_config_needs_its_tag():
    class Untagged(seamless.SeamlessRoadConfig):
        type: str = "x"

    with pytest.raises(TypeError, match="Literal"):
        _ = Family(Untagged, _build).tag
