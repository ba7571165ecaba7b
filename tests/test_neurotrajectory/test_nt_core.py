"""NeuroTrajectory building blocks: network, genomes, Pareto sorting, selection."""

from dataclasses import replace

import moocore
import numpy as np
import pytest
import torch
from golden import numerics_platform
from pymoo.operators.survival.rank_and_crowding.metrics import calc_crowding_distance

from gridsim.sensors.occupancy_kernels import pooled_convolution
from neurotrajectory.curves import CurveLimits, destination_curves
from neurotrajectory.evolve.evolution import GAConfig, initial_recipes, next_generation
from neurotrajectory.evolve.genome import (
    Recipe,
    apply_recipe,
    get_genome,
    initial_genome,
    noise_table,
    set_genome,
)
from neurotrajectory.evolve.pareto import (
    crowding_distance,
    generation_hypervolume,
    hypervolume,
    hypervolume_ratio,
    minimised,
    non_dominated_sort,
)
from neurotrajectory.model import PRESETS, NetConfig, TrajectoryNet, block_means, count_parameters


def test_presets_sizes_and_output_shape():
    assert count_parameters(TrajectoryNet(PRESETS["paper"])) == pytest.approx(19.0e6, rel=0.01)
    net = TrajectoryNet(PRESETS["default"])
    assert count_parameters(net) == 405_050 + 5 * 2 * 15  # + the skip read-out
    out = net(torch.zeros(3, 5, 128, 128, dtype=torch.uint8), torch.zeros(3, 6), torch.zeros(3, 2))
    assert out.shape == (3, 5, 2)
    with pytest.raises(ValueError, match="activation"):
        NetConfig(activation="swish")
    with pytest.raises(ValueError, match="divisible"):
        NetConfig(grid_size=100)


def test_fused_branches_equal_separate_lstms():
    from torch import nn

    from neurotrajectory.model import BranchLSTMs

    torch.manual_seed(0)
    fused = BranchLSTMs(3, 16, 8)
    x = torch.randn(4, 5, 16)
    with torch.no_grad():
        out = fused(x)
        for k in range(3):
            lstm, head = nn.LSTM(16, 8, batch_first=True), nn.Linear(8, 2)
            lstm.weight_ih_l0.copy_(fused.weight_ih[k])
            lstm.weight_hh_l0.copy_(fused.weight_hh[k])
            lstm.bias_ih_l0.copy_(fused.bias_ih[k])
            lstm.bias_hh_l0.copy_(fused.bias_hh[k])
            head.weight.copy_(fused.head_weight[k])
            head.bias.copy_(fused.head_bias[k])
            ref = head(lstm(x)[1][0][-1])
            torch.testing.assert_close(out[:, k], ref, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("prior", ["constant_velocity", "destination_curve"])
def test_a_zero_network_outputs_its_prior(prior):
    net = TrajectoryNet(replace(PRESETS["tiny"], prior=prior))
    set_genome(net, np.zeros(count_parameters(net), np.float32))  # the network adds nothing
    ego = torch.tensor([[10.0, 0.0, 0.0, 0.0, 0.6, 0.8]])
    dest = torch.tensor([[12.0, 21.0]])  # 2.5 s ahead, 3 m left of the heading
    with torch.no_grad():
        out = net(torch.zeros(1, 5, 128, 128, dtype=torch.uint8), ego, dest)[0].numpy()
    t = 0.5 * np.arange(1, 6)
    if prior == "constant_velocity":
        want = np.stack([10 * t * 0.6, 10 * t * 0.8], 1)
    else:
        want = destination_curves(ego.numpy(), dest.numpy(), t, CurveLimits())[0]
        np.testing.assert_allclose(want[-1], dest[0], atol=1e-4)  # it arrives
    np.testing.assert_allclose(out, want, atol=1e-5)


def test_noise_table_is_the_same_everywhere():
    t = noise_table(1 << 22)
    # NumPy's PCG64 + ziggurat: fixed bits on every platform (torch.randn is not).
    np.testing.assert_array_equal(
        t[:4], np.array([0.0012738787, 1.0034029, 1.4405828, 0.18512645], np.float32)
    )
    assert abs(float(t.std()) - 1.0) < 1e-3
    assert not t.flags.writeable


def test_genome_round_trip_and_recipes():
    net = TrajectoryNet(PRESETS["tiny"])
    g = initial_genome(net, 5)
    np.testing.assert_array_equal(g, initial_genome(net, 5))
    set_genome(net, g)
    np.testing.assert_array_equal(get_genome(net), g)
    table = noise_table(1 << 22)
    parents = np.stack([g, -g])
    mut = apply_recipe(Recipe(parent=0, noise_offset=100, sigma=0.5), parents, table)
    np.testing.assert_array_equal(mut, g + np.float32(0.5) * table[100 : 100 + len(g)])
    cross = apply_recipe(Recipe(parent=0, other=1, crossover_seed=9), parents, table)
    from_other = cross == -g
    assert 0.4 < from_other[g != 0].mean() < 0.6  # uniform crossover: each weight 50/50
    np.testing.assert_array_equal(cross[~from_other], g[~from_other])
    assert Recipe(parent=3).is_elite and np.array_equal(
        apply_recipe(Recipe(parent=1), parents, table), -g
    )


@pytest.mark.parametrize("seed", range(6))
def test_non_dominated_sort_matches_moocore_with_ties_and_duplicates(seed):
    rng = np.random.default_rng(seed)
    n, m = rng.integers(1, 200), rng.integers(2, 4)
    f = rng.integers(0, 5, size=(n, m)).astype(float)  # many ties and duplicates
    f = np.vstack([f, f[: n // 4]])
    np.testing.assert_array_equal(non_dominated_sort(f), moocore.pareto_rank(f))
    g = rng.random((n, m))
    np.testing.assert_array_equal(non_dominated_sort(g), moocore.pareto_rank(g))


@pytest.mark.parametrize("seed", range(4))
def test_crowding_matches_pymoo(seed):
    rng = np.random.default_rng(seed)
    f = rng.random((30, 3))
    f = np.vstack([f, f[:4]])  # duplicates
    m = f.shape[1]
    # pymoo divides by the number of objectives; Deb's NSGA-II (ours) does not.
    np.testing.assert_allclose(crowding_distance(f) / m, calc_crowding_distance(f), rtol=1e-12)


def test_crowding_hand_computed():
    f = np.array([[0.0, 4.0], [1.0, 2.0], [2.0, 1.0], [4.0, 0.0]])
    d = crowding_distance(f)
    assert np.isinf(d[0]) and np.isinf(d[3])
    assert d[1] == pytest.approx(2 / 4 + 3 / 4) and d[2] == pytest.approx(3 / 4 + 2 / 4)


def test_hypervolume_known_value():
    assert hypervolume(np.array([[0.5, 0.5]]), np.array([1.0, 1.0])) == pytest.approx(0.25)
    assert hypervolume(np.array([[2.0, 2.0]]), np.array([1.0, 1.0])) == 0.0


def test_hypervolume_ratio_is_measured_against_the_reference_alone():
    """1 when no member goes beyond the reference; a member 10 % better in all three (l3 is
    maximised) doubles the box's side: 8x; members that lost time or stood still do not count."""
    ref = np.array([100.0, 2.0, 500.0])
    assert hypervolume_ratio(ref[None], ref) == pytest.approx(1.0)
    better = np.array([[90.0, 1.8, 500.0 / 0.9]])
    assert hypervolume_ratio(np.vstack([ref, better]), ref) == pytest.approx(8.0)
    worse = np.array([[200.0, 4.0, 100.0], [0.0, 0.0, 0.0]])  # the second never moved
    assert hypervolume_ratio(np.vstack([ref, worse]), ref) == pytest.approx(1.0)
    lost = np.array([0.0, 0.3])
    assert hypervolume_ratio(np.vstack([ref, better]), ref, lost) == pytest.approx(1.0)


def test_a_generation_is_measured_against_its_own_anchor_or_generation_0s_median():
    """The figure of the hypervolume plot and of train's progress bar."""
    ref = [100.0, 2.0, 500.0]
    better = [90.0, 1.8, 500.0 / 0.9]
    first = {"fitness": [[200.0, 4.0, 250.0], ref, [50.0, 1.0, 1000.0]]}  # median: ref
    record = {"fitness": [ref, better], "violation": [0.0, 0.0]}
    assert generation_hypervolume(record, first, anchored=True) == pytest.approx(8.0)
    assert generation_hypervolume(record, first, anchored=False) == pytest.approx(8.0)
    behind = {"fitness": [better, ref], "violation": [0.0, 0.0]}  # the anchor is the better one
    assert generation_hypervolume(behind, first, anchored=True) == pytest.approx(1.0)
    assert generation_hypervolume(behind, first, anchored=False) == pytest.approx(8.0)
    lost = {"fitness": [ref, better], "violation": [0.0, 0.2]}
    assert generation_hypervolume(lost, first, anchored=True) == pytest.approx(1.0)


def test_selection_keeps_the_front_and_is_reproducible():
    rng = np.random.default_rng(0)
    fit = np.column_stack([rng.random(20) * 100, rng.random(20), rng.random(20) * 50])
    cfg = GAConfig(population=20, elite_fraction=0.25)
    a, rank = next_generation(fit, cfg, seed=3, generation=7, genome_size=1000, table_size=4096)
    b, _ = next_generation(fit, cfg, seed=3, generation=7, genome_size=1000, table_size=4096)
    assert a == b and len(a) == 20
    elites = [r for r in a if r.is_elite]
    assert 1 <= len(elites) <= 5
    assert all(rank[r.parent] == 0 for r in elites)
    np.testing.assert_array_equal(rank, moocore.pareto_rank(minimised(fit)))
    children = [r for r in a if not r.is_elite]
    assert all(r.noise_offset is not None or r.other is not None for r in children)
    assert all(r.noise_offset is None or 0 <= r.noise_offset <= 4096 - 1000 for r in children)
    c, _ = next_generation(fit, cfg, seed=3, generation=8, genome_size=1000, table_size=4096)
    assert c != a
    assert len(initial_recipes(cfg, 0)) == 20


def test_no_child_is_an_exact_copy_of_its_parent():
    """A crossover whose second tournament picked the first parent again would give the parent
    itself: such a child is mutated instead (3-6 % of small runs' evaluations were copies)."""
    rng = np.random.default_rng(1)
    cfg = GAConfig(population=24, elite_fraction=0.25)
    seen_self_pick = 0
    for generation in range(40):
        fit = np.column_stack([rng.random(24) * 100, rng.random(24), rng.random(24) * 50])
        recipes, _ = next_generation(fit, cfg, seed=5, generation=generation, genome_size=10,
                                     table_size=100)  # fmt: skip
        for r in recipes:
            if r.is_elite:
                continue
            assert r.other != r.parent, r
            assert r.noise_offset is not None or r.other is not None, r
            assert (r.other is None) == (r.crossover_seed is None), r
        seen_self_pick += sum(r.other is None and r.noise_offset is not None for r in recipes)
    assert seen_self_pick > 0


def test_constrained_sort_puts_completing_first():
    # objectives to minimise; point 2 dominates everything but violates the constraint
    f = np.array([[3.0, 3.0], [1.0, 4.0], [0.0, 0.0], [0.5, 0.5], [2.0, 2.0]])
    violation = np.array([0.0, 0.0, 0.5, 0.2, 0.0])
    rank = non_dominated_sort(f, violation)
    # feasible points by Pareto dominance first ([2, 2] dominates [3, 3]); then the smaller
    # violation, whatever the objectives
    np.testing.assert_array_equal(rank, [1, 0, 3, 2, 0])
    np.testing.assert_array_equal(non_dominated_sort(f, np.zeros(5)), non_dominated_sort(f))
    with pytest.raises(ValueError, match="violation must be 5 numbers >= 0"):
        non_dominated_sort(f, -np.ones(5))


def test_selection_never_keeps_a_failing_member_over_a_completing_one():
    rng = np.random.default_rng(0)
    fitness = np.column_stack(
        [rng.uniform(1, 10, 12), rng.uniform(0, 1, 12), rng.uniform(0, 5, 12)]
    )
    fitness[0] = [0.0, 0.0, 100.0]  # the best in every objective, but it crashed
    violation = np.zeros(12)
    violation[0] = 0.1
    cfg = GAConfig(population=12, elite_fraction=0.5)
    recipes, rank = next_generation(fitness, cfg, 0, 0, 10, 100, violation)
    assert rank[0] > 0 and rank.min() == 0
    assert all(r.parent != 0 for r in recipes if r.is_elite)


@pytest.mark.parametrize("p", [1, 2, 3, 4, 8])
def test_block_means_are_avg_pool_bit_for_bit(p):
    """The integer block sums the rollouts pool with give exactly what ``avg_pool2d`` gives
    on the float values (the training digests depend on it), at the extremes too."""
    rng = np.random.default_rng(p)
    frames = rng.integers(0, 256, size=(3, 8 * p, 16 * p), dtype=np.uint8)
    frames[0] = 255  # the largest sums
    want = torch.from_numpy(frames).float()[:, None]
    if p > 1:
        want = torch.nn.functional.avg_pool2d(want, p)
    got = block_means(frames, p)
    assert got.dtype == torch.float32 and got.shape == want.shape
    assert torch.equal(got, want)
    if p > 1:
        with pytest.raises(ValueError, match=f"do not split into blocks of {p} x {p}"):
            block_means(frames[:, 1:], p)


@pytest.mark.parametrize(
    ("p", "size", "stride", "pad"),
    [(2, 5, 2, 2), (1, 5, 2, 2), (4, 3, 2, 1), (2, 3, 1, 1), (1, 4, 3, 0), (2, 5, 3, 1)],
)
def test_pooled_convolution_gives_the_bits_of_conv2d(p, size, stride, pad):
    """The rollouts' compiled first convolution (pooling, scaling, ``conv2d`` with one input
    channel and its ReLU, for several sets of weights) gives torch's bits: each output sums
    its products in ``conv2d``'s order, fused. Weights are read through strided views.
    Measured on AVX-512 CPUs (Intel, AMD); elsewhere the rollouts' probe decides whether it
    is used (:meth:`PopulationNet.convolutions`)."""
    if "/AVX512/" not in numerics_platform():
        pytest.skip("conv2d's order measured on AVX-512 CPUs; elsewhere the probe decides")
    rng = np.random.default_rng(size * 10 + stride)
    k, e, c, side = 3, 2, 4, 24 * p
    frames = rng.choice(np.array([0, 128, 255], np.uint8), size=(k, e, side, side))
    frames[0, 0] = rng.integers(0, 256, size=(side, side))
    frames[1, 1] = 255  # the largest sums
    weight = rng.standard_normal((k, c, 2, size, size)).astype(np.float32)[:, :, 1]  # strided
    bias = 0.1 * rng.standard_normal((k, c)).astype(np.float32)
    x = block_means(frames.reshape(k * e, side, side), p) / 255.0
    want = torch.stack([torch.nn.functional.conv2d(
        x[i * e : (i + 1) * e], torch.from_numpy(weight[i][:, None].copy()),
        torch.from_numpy(bias[i]), stride, pad).relu_() for i in range(k)], 1)  # fmt: skip
    out = np.full((e, k * c, *want.shape[3:]), np.nan, np.float32)
    pooled_convolution(frames, p, weight, bias, stride, pad, out)
    assert torch.equal(torch.from_numpy(out).view(want.shape), want)


def test_networks_drive_and_predict_on_one_thread_whatever_the_caller_set():
    """Closed-loop results changed with torch's thread count (a command's own process has as
    many as cores, a worker 1: heldout.json differed between backends and machines in the
    last digits): a policy, a predictor and End2End compute on one thread, then put the
    caller's count back."""
    from neurotrajectory.compare.front import NetPredictor
    from neurotrajectory.model import NetPolicy, one_thread

    seen = []
    net = TrajectoryNet(PRESETS["tiny"])
    forward = net.forward
    net.forward = lambda *a: (seen.append(torch.get_num_threads()), forward(*a))[1]
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        cfg = net.cfg
        obs = {"grids": np.zeros((cfg.history, cfg.grid_size, cfg.grid_size), np.uint8),
               "ego": np.zeros(6, np.float32), "destination": np.ones(2, np.float32)}  # fmt: skip
        NetPolicy(net, smoothing=0.0)(None, obs, {})
        assert seen == [1] and torch.get_num_threads() == 2

        class Batch:  # what window_inputs reads
            grids = obs["grids"][None]
            ego = obs["ego"][None]
            destination = obs["destination"][None]
            target = np.zeros((1, cfg.horizon, 2), np.float32)

            def __len__(self):
                return 1

        NetPredictor(net).predict(Batch())
        assert seen == [1, 1] and torch.get_num_threads() == 2
        with one_thread():
            assert torch.get_num_threads() == 1
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
