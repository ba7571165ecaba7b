"""Bit-identity: rollouts, recorded datasets and a short training run reproduce the digests
recorded from the reference implementation (see ``tests/golden.py``), so that speed-ups and
restructuring cannot change any result."""

import json

import pytest
from golden import (
    DATASET_CASES,
    GOLDEN_PATH,
    WORLD_CASES,
    dataset_digests,
    env_cases,
    env_digests,
    training_digests,
    world_digests,
)

GOLDEN = json.loads(GOLDEN_PATH.read_text())


@pytest.mark.parametrize(("scenario", "seed", "policy"), env_cases())
def test_env_rollout_is_bit_identical_to_golden(scenario, seed, policy):
    assert env_digests(scenario, seed, policy) == GOLDEN["env"][f"{scenario}/{seed}/{policy}"]


@pytest.mark.parametrize(("name", "scenario", "overrides", "ticks"), WORLD_CASES)
def test_world_ticks_are_bit_identical_to_golden(name, scenario, overrides, ticks):
    assert world_digests(scenario, overrides, ticks) == GOLDEN["world"][name]


@pytest.mark.parametrize("case", DATASET_CASES, ids=lambda c: f"{c[0]}/{c[2]}")
def test_recorded_datasets_are_bit_identical_to_golden(case):
    assert dataset_digests(*case) == GOLDEN["datasets"][f"{case[0]}/{case[2]}"]


def test_a_short_training_run_is_bit_identical_to_golden(tmp_path):
    assert training_digests(tmp_path / "run") == GOLDEN["training"]
