"""Evolution strategies (``--selection es``): a centre and antithetic pairs around it, the
centre moved by the pairs' rank-weighted noise; reproducible, resumable, process-identical."""

import json

import numpy as np
import pytest
from golden import run_history, untimed_history

from neurotrajectory.evolve.evolution import (
    ANCHOR,
    GAConfig,
    es_centre,
    es_recipes,
    es_utilities,
)
from neurotrajectory.evolve.genome import apply_recipe, noise_table
from neurotrajectory.evolve.runs import Run, RunError, TrainConfig

#: Training runs, rollouts or subprocesses: left out of the quick loop (`pytest -m "not slow"`).
pytestmark = pytest.mark.slow

ES = dict(preset="tiny", population=6, generations=3, episodes=1, episode_seconds=3.0, seed=2,
          pretrain_episodes=2, pretrain_epochs=1, validation_episodes=2, batch=3,
          selection="es", es_step=2.0)  # fmt: skip


@pytest.fixture(scope="module")
def es_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("es") / "run"
    Run.create(out, TrainConfig(**ES)).train(progress=False)
    return out


def test_a_generation_is_the_centre_and_antithetic_pairs():
    rng = np.random.default_rng(0)
    recipes = es_recipes(GAConfig(population=6, sigma=0.01), rng, 10, 100)
    assert recipes[0].is_elite and recipes[0].parent == 0
    pairs = [recipes[1:3], recipes[3:5]]
    for plus, minus in pairs:
        assert plus.noise_offset == minus.noise_offset and plus.sigma == -minus.sigma == 0.01
    assert recipes[5].sigma == 0.01 and len(recipes) == 6  # the odd member left over
    table = noise_table(100)
    centre = np.arange(10, dtype=np.float32)
    plus, minus = (apply_recipe(r, centre[None], table) for r in pairs[0])
    np.testing.assert_allclose((plus + minus) / 2, centre, atol=1e-6)


def test_utilities_rank_lost_time_first_then_l1():
    fitness = np.array([[9.0, 0, 0], [5.0, 0, 0], [1.0, 0, 0], [3.0, 0, 0], [0.5, 0, 0]])
    lost = np.array([0.0, 0.0, 0.0, 0.0, 0.2])  # the lowest l1 lost time: the worst
    np.testing.assert_allclose(es_utilities(fitness, lost), [-1 / 6, 0.5, 1 / 6, -0.5])


def test_the_centre_moves_toward_the_better_member_of_each_pair():
    n, sigma = 50, 0.1
    rng = np.random.default_rng(1)
    centre = rng.standard_normal(n).astype(np.float32)
    e = rng.standard_normal((2, n)).astype(np.float32)
    genomes = np.stack([centre, centre + sigma * e[0], centre - sigma * e[0],
                        centre + sigma * e[1], centre - sigma * e[1]])  # fmt: skip
    # pair 0: + is the best member, - the worst; pair 1: - beats +
    fitness = np.array([[9.0, 0, 0], [1.0, 0, 0], [4.0, 0, 0], [3.0, 0, 0], [2.0, 0, 0]])
    lost = np.zeros(5)
    new = es_centre(genomes, fitness, lost, step=1.5)
    u = es_utilities(fitness, lost)
    want = centre + 1.5 * ((u[0] - u[1]) * sigma * e[0] + (u[2] - u[3]) * sigma * e[1]) / 2
    np.testing.assert_allclose(new, want, rtol=1e-5, atol=1e-6)
    assert np.dot(new - centre, e[0]) > 0  # toward pair 0's + member
    assert new.dtype == np.float32 and np.array_equal(new, es_centre(genomes, fitness, lost, 1.5))


def test_an_es_run_keeps_its_centre_first_and_validates_it(es_run):
    run = Run.open(es_run)
    hist = run_history(es_run)
    warm = run.warm_start_genome()
    assert all(h["knee_validation"]["index"] == ANCHOR for h in hist)
    assert hist[0]["warm_start_validation"] == hist[0]["knee_validation"]  # the first centre
    _, population, fitness, lost = run.load_checkpoint()
    assert not np.array_equal(population[ANCHOR], warm)  # the centre moved
    # the last generation is its centre and pairs around it
    pairs = population[1:5].reshape(2, 2, -1)
    np.testing.assert_allclose(pairs.mean(axis=1), population[[ANCHOR, ANCHOR]], atol=1e-6)


def test_an_es_runs_front_json_names_no_candidate_as_its_warm_start(es_run):
    """front.json's warm start is the warm start's scores on the validation episodes; an
    ``index`` would name a candidate (as the front's entries do), but candidate 0 of an ES
    run is its last centre, moved from the warm start, and no candidate is the warm start."""
    run = Run.open(es_run)
    summary = json.loads((es_run / "front.json").read_text())
    _, population, _, _ = run.load_checkpoint()
    assert not any(np.array_equal(g, run.warm_start_genome()) for g in population)
    warm = summary["warm_start"]
    assert "index" not in warm
    scores = run_history(es_run)[0]["warm_start_validation"]  # on the same episodes
    assert warm == {k: v for k, v in scores.items() if k != "index"}
    assert summary["candidates"][ANCHOR]["l1"] != warm["l1"]  # (candidate 0: the centre)


def test_an_es_run_resumes_and_runs_on_processes_to_the_same_bits(es_run, tmp_path):
    out = tmp_path / "resumed"
    Run.create(out, TrainConfig(**ES)).train(progress=False, stop_after=1)
    Run.open(out).train(progress=False)
    other = tmp_path / "processes"
    Run.create(other, TrainConfig(**ES, backend="processes", workers=2)).train(progress=False)

    for folder in (out, other):
        assert untimed_history(folder) == untimed_history(es_run)
        with np.load(es_run / "checkpoint.npz") as a, np.load(folder / "checkpoint.npz") as b:
            assert np.array_equal(a["population"], b["population"])


def test_es_needs_a_warm_start_and_a_sane_step():
    with pytest.raises(RunError, match="--selection es starts from the warm start"):
        TrainConfig(selection="es")
    for bad in (0.0, -1.0, float("nan"), 1e9):
        with pytest.raises(RunError, match=r"es_step must be a finite number in \(0, 100\]"):
            TrainConfig(**{**ES, "es_step": bad})
