"""Batched population evaluation: an individual's fitness never depends on its batch."""

import json
from dataclasses import replace

import numpy as np
import pytest
import torch
from golden import numerics_platform

from neurotrajectory import model
from neurotrajectory.evolve.backends import WorkerSpec, make_backend
from neurotrajectory.evolve.fitness import Evaluator
from neurotrajectory.evolve.genome import Recipe, initial_genome, set_genome
from neurotrajectory.evolve.runs import Run, TrainConfig
from neurotrajectory.model import PRESETS, Convolutions, NetConfig, PopulationNet, TrajectoryNet

#: Training runs, rollouts or subprocesses: left out of the quick loop (`pytest -m "not slow"`).
pytestmark = pytest.mark.slow

SHORT = {"simulation": {"duration": 3.0}}
#: The batched forward pass versus TrajectoryNet: float rounding only (observed <= 2.4e-7 m).
FORWARD_TOLERANCE = 1e-5


def _population(net, count, seed=0):
    """Initial genomes plus strongly mutated ones (their episodes end early, at different
    steps, so that individuals and episodes drop out of the batch mid-way)."""
    rng = np.random.default_rng(seed)
    pop = np.stack([initial_genome(net, s) for s in range(count)])
    for i in range(1, count, 3):
        pop[i] += np.float32(0.3) * rng.standard_normal(pop.shape[1], dtype=np.float32)
    return pop


def _inputs(k, e, cfg, seed=0):
    rng = np.random.default_rng(seed)
    grids = ((rng.random((k, e, cfg.history, 128, 128)) < 0.2) * 255).astype(np.uint8)
    ego = torch.from_numpy(rng.normal(size=(k, e, 6)).astype(np.float32))
    dest = torch.from_numpy(rng.normal(scale=10.0, size=(k, e, 2)).astype(np.float32))
    return grids, ego, dest


@pytest.mark.parametrize("preset", ["tiny", "default", "tiny-legacy", "tiny-bounded"])
def test_population_forward_matches_trajectorynet_and_ignores_the_batch(preset):
    torch.set_num_threads(1)
    if preset.endswith("-legacy"):  # networks saved before the ego-frame residual and skip
        cfg = NetConfig.from_dict({**PRESETS["tiny"].to_dict(), **NetConfig.LEGACY})
    elif preset.endswith("-bounded"):  # corrections squashed (tanh): still batch-invariant
        cfg = replace(PRESETS["tiny"], max_correction=(0.5, 0.2))
    else:
        cfg = PRESETS[preset]
    net = TrajectoryNet(cfg).eval()
    pnet = PopulationNet(cfg)
    k, e = 5, 2
    pop = _population(net, k)
    grids, ego, dest = _inputs(k, e, cfg)
    with torch.no_grad():
        together = pnet.forward(pop, grids, ego, dest)
        for i in range(k):
            set_genome(net, pop[i])
            ref = net(torch.from_numpy(grids[i]), ego[i], dest[i])
            assert float((together[i] - ref).abs().max()) < FORWARD_TOLERANCE
            alone = pnet.forward(pop[i : i + 1], grids[i : i + 1], ego[i : i + 1], dest[i : i + 1])
            assert torch.equal(alone[0], together[i])
        shifted = pnet.forward(pop[::-1].copy(), grids[::-1].copy(), ego.flip(0), dest.flip(0))
        assert torch.equal(shifted.flip(0), together)


@pytest.mark.parametrize("preset", ["default", "paper"])
def test_frame_features_are_those_of_one_convolution_call_per_individual(preset):
    """Every choice of :meth:`PopulationNet.convolutions` (all convolutions, or those after
    the first, as one grouped call for all individuals; the first compiled) gives the bits of
    one call per individual (on other frames and weights than the probe's); one frame per
    individual is never grouped."""
    torch.set_num_threads(1)
    cfg = PRESETS[preset]
    pnet = PopulationNet(cfg)
    pop = _population(TrajectoryNet(cfg), 16, seed=4)
    store = pnet.store(pop)
    for k, e in ((1, 2), (3, 2), (16, 2), (5, 3), (4, 1)):
        params = pnet.params(store, pnet.small_copy(store), np.arange(k))
        frames = _inputs(k, e, cfg, seed=k)[0][:, :, 0]
        x = pnet._pooled(frames)
        one_per_individual = pnet._features_per_individual(params, x)
        assert torch.equal(pnet.frame_features(params, frames), one_per_individual)
        if e > 1 and "/AVX512/" in numerics_platform():  # (one frame: torch convolves each
            # individual otherwise than grouped; elsewhere than where it was measured, the
            # probe decides whether the compiled first convolution gives these bits)
            assert torch.equal(pnet._features_compiled(params, frames), one_per_individual)
        plan = pnet.convolutions(k, e)
        if plan in (Convolutions.GROUPED, Convolutions.GROUPED_AFTER_FIRST):
            grouped = pnet._features_grouped(params, x, plan.first_grouped)
            assert torch.equal(grouped, one_per_individual)
    assert pnet.convolutions(4, 1) is Convolutions.PER_INDIVIDUAL
    if "/AVX512/" in numerics_platform():  # where it was measured (Intel and AMD)
        assert pnet.convolutions(16, 2) is not Convolutions.PER_INDIVIDUAL, (
            "the grouped convolutions are no longer used"
        )


def _results(ev, pop):
    return [(f.tolist(), s.__dict__) for f, s in ev.evaluate_many(pop)]


def test_fitness_does_not_depend_on_the_batch_nor_on_the_frame_cache():
    ev = Evaluator("seamless", SHORT, PRESETS["tiny"], [5, 6], batch=1)
    pop = _population(ev.net, 8)
    alone = _results(ev, pop)
    steps = [s["steps"] for _, s in alone]
    assert min(steps) < max(steps)  # some episodes end early: the batch shrinks mid-way
    for batch in (2, 5, 8, 16):
        ev.batch = batch
        assert _results(ev, pop) == alone
    ev.batch = 3  # other positions in the batches
    assert _results(ev, pop[::-1].copy())[::-1] == alone
    ev.batch, ev.cache = 8, False  # every frame recomputed every step
    assert _results(ev, pop) == alone
    fitness, stats = ev.evaluate(pop[2])
    assert (fitness.tolist(), stats.__dict__) == alone[2]


def test_big_parameters_used_in_place_do_not_depend_on_the_batch(monkeypatch):
    monkeypatch.setattr(model, "BIG_PARAMETER", 2048)  # tiny's fc1 and LSTM input weights
    ev = Evaluator("seamless", SHORT, PRESETS["tiny"], [7], batch=1)
    assert {"encoder.fc.0.weight", "branches.weight_ih"}.isdisjoint(ev.pop_net.small)
    pop = _population(ev.net, 7, seed=1)
    alone = _results(ev, pop)
    for batch in (3, 7):
        ev.batch = batch
        assert _results(ev, pop) == alone


def test_backends_and_batch_sizes_give_identical_results():
    recipes = [Recipe(init_seed=i) for i in range(5)]
    children = [Recipe(parent=0), Recipe(parent=1, other=2, crossover_seed=3),
                Recipe(parent=3, noise_offset=10, sigma=0.3), Recipe(parent=2),
                Recipe(parent=4, noise_offset=99, sigma=0.3)]  # fmt: skip
    results = {}
    for name, batch in (("local", 1), ("local", 16), ("processes", 2), ("ray", 3)):
        spec = WorkerSpec("seamless", SHORT, PRESETS["tiny"], (5, 6), batch=batch)
        backend = make_backend(name, spec, workers=2)
        try:
            backend.advance(recipes)
            backend.advance(children)
            results[name, batch] = backend.evaluate(5, spec.seeds)
        finally:
            backend.close()
    ref_fitness, ref_stats = results["local", 1]
    for fitness, stats in results.values():
        np.testing.assert_array_equal(fitness, ref_fitness)
        assert stats == ref_stats


def test_training_history_does_not_depend_on_the_batch(tmp_path):
    cfg = dict(preset="tiny", population=6, episodes=2, episode_seconds=3.0, seed=2,
               generations=2)  # fmt: skip
    Run.create(tmp_path / "a", TrainConfig(batch=1, **cfg)).train(progress=False)
    Run.create(tmp_path / "b", TrainConfig(batch=4, **cfg)).train(progress=False)

    def fitness(out):
        return [h["fitness"] for h in json.loads((out / "history.json").read_text())["generations"]]

    assert fitness(tmp_path / "a") == fitness(tmp_path / "b")
