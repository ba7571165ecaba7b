"""Bit-identity: rollouts, recorded datasets and a short training run reproduce the digests
recorded from the reference implementation (see ``tests/golden.py``), so that speed-ups and
restructuring cannot change any result."""

import json

import pytest
from golden import (
    DATASET_CASES,
    GOLDEN_PATH,
    TRAINING_PATHS,
    WORLD_CASES,
    dataset_digests,
    env_cases,
    env_digests,
    numerics_platform,
    run_digests,
    training_digests,
    training_golden,
    training_path_digests,
    world_digests,
)

#: Training runs, rollouts or subprocesses: left out of the quick loop (`pytest -m "not slow"`).
pytestmark = pytest.mark.slow

GOLDEN = json.loads(GOLDEN_PATH.read_text())


def _training(section: str) -> dict:
    """The training digests recorded for this machine's numerics (a skip when there are none:
    torch's rounding differs between CPU vendors and instruction sets)."""
    golden = training_golden(GOLDEN, section)
    if golden is None:
        pytest.skip(f"no {section} digests recorded for {numerics_platform()} "
                    "(python tests/golden.py training training_paths)")  # fmt: skip
    return golden


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
    assert training_digests(tmp_path / "run") == _training("training")


@pytest.mark.parametrize("name", TRAINING_PATHS)
def test_the_trainers_other_paths_are_bit_identical_to_golden(name, tmp_path):
    recorded = _training("training_paths")
    if name not in recorded:
        pytest.skip(f"no {name} digests recorded for {numerics_platform()} "
                    "(python tests/golden.py training_paths)")  # fmt: skip
    assert training_path_digests(tmp_path / name, name) == recorded[name]


def test_a_run_resumed_on_worker_processes_is_bit_identical_to_golden(tmp_path):
    from neurotrajectory.evolve.runs import Run, TrainConfig

    out = tmp_path / "run"
    Run.create(out, TrainConfig(**TRAINING_PATHS["random_init"])).train(
        progress=False, stop_after=1
    )
    Run.open(out, backend="processes", workers=2).train(progress=False)
    assert run_digests(out) == _training("training_paths")["random_init"]
