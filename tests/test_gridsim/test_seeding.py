"""Named random streams: one salt per use, never shared."""

import numpy as np

from gridsim.seeding import Salt, stream


def test_every_salt_is_its_own_stream():
    values = [int(s) for s in Salt]
    assert len(set(values)) == len(values)
    draws = {s: stream(7, s).integers(0, 2**62, size=4).tolist() for s in Salt}
    assert len({tuple(d) for d in draws.values()}) == len(Salt)


def test_streams_are_the_seed_sequences_of_their_numbers():
    # the streams the trainer drew before the salts were named: same numbers, same draws
    old = np.random.default_rng(np.random.SeedSequence([5, 0x4E1D])).integers(0, 2**30, 8)
    new = stream(np.int64(5), Salt.HELDOUT_EPISODES).integers(0, 2**30, 8)
    np.testing.assert_array_equal(old, new)


def test_a_copied_generator_draws_what_a_deep_copy_draws():
    import copy

    from gridsim.seeding import copy_generator

    g = np.random.default_rng(123)
    g.uniform(size=3)
    g.integers(5)  # may leave half a 64-bit word buffered
    fast, deep = copy_generator(g), copy.deepcopy(g)
    assert fast.bit_generator.state == deep.bit_generator.state

    def draws(rng):
        return [rng.integers(7, size=5), rng.uniform(size=3), rng.permutation(6), rng.integers(9)]

    expected = draws(deep)
    assert all(np.array_equal(a, b) for a, b in zip(draws(fast), expected, strict=True))
    assert all(np.array_equal(a, b) for a, b in zip(draws(g), expected, strict=True))  # apart
