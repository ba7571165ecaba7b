"""Bit-identity: rollouts reproduce the digests recorded from the reference implementation
(see ``tests/golden.py``), so that speed-ups of the step path cannot change any result."""

import json

import pytest
from golden import GOLDEN_PATH, WORLD_CASES, env_cases, env_digests, world_digests

GOLDEN = json.loads(GOLDEN_PATH.read_text())


@pytest.mark.parametrize(("scenario", "seed", "policy"), env_cases())
def test_env_rollout_is_bit_identical_to_golden(scenario, seed, policy):
    assert env_digests(scenario, seed, policy) == GOLDEN["env"][f"{scenario}/{seed}/{policy}"]


@pytest.mark.parametrize(("name", "scenario", "overrides", "ticks"), WORLD_CASES)
def test_world_ticks_are_bit_identical_to_golden(name, scenario, overrides, ticks):
    assert world_digests(scenario, overrides, ticks) == GOLDEN["world"][name]
