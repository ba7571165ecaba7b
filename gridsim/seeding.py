"""The project's named random streams.

Every salted random stream derived from a user's seed comes from :func:`stream` with a
:class:`Salt`, so that no two uses share a stream and each salt is written once (a world
build splits its seed with ``SeedSequence.spawn`` instead, and generators seeded directly by
a recipe or a road seed need no salt). The values
are fixed forever: changing one changes every result drawn from it.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

#: The largest seed a user gives (a flag, a training run's ``seed``).
MAX_SEED = 2**32 - 1
#: Episode seeds are drawn below this (:func:`episode_seed`).
EPISODE_SEEDS = 2**31 - 1


def episode_seed(seed: int) -> int:
    """The episode seed ``GridSimEnv.reset(seed=seed)`` draws first (``info["episode_seed"]``:
    the world, the reference and a collection's scenario are made from it), for a command
    that builds the episode's world without an environment (``gridsim drive``)."""
    from gymnasium.utils.seeding import np_random

    return int(np_random(seed)[0].integers(EPISODE_SEEDS))


class Salt(IntEnum):
    """What a random stream is for (simulator, then trainer and evaluation)."""

    HUMAN_PROFILE = 0x5EF  # the generated human reference's speed and lane profile
    SCENARIO_PICK = 0x5CE7E  # the scenario of a folder or glob an episode seed picks
    NOISE_TABLE = 0x6E5  # the trainer's shared Gaussian noise table (no user seed)
    GENERATION = 0x6A  # a generation's selection, crossover and mutation
    EPISODES = 0xE915  # the training episodes of a generation
    PRETRAIN_EPISODES = 0x9E7B  # the episodes recorded for the warm start
    VALIDATION_EPISODES = 0x7A11D  # the episodes the final front is chosen on
    VALIDATION_TRACKS = 0x7A1D7  # the training tracks kept out of evolution to validate on
    HELDOUT_EPISODES = 0x4E1D  # episodes no generation trains on
    WARM_START_MUTATIONS = 0x9E7A  # generation 0 around the fitted network
    WARM_START_BATCHES = 0x9E7  # the order of the warm start's mini-batches
    RECORDED_EPISODES = 0xDA7A  # the episode seeds `record` draws
    TRACK_SPLIT = 0x5B17  # the train / test split by track
    CLOSED_LOOP_EPISODES = 0xC10  # the evaluation's closed-loop episodes


def stream(*entropy: int) -> np.random.Generator:
    """A generator seeded with ``entropy`` (a user's seed, a :class:`Salt`, more numbers)."""
    return np.random.default_rng(np.random.SeedSequence([int(e) for e in entropy]))


def copy_generator(g: np.random.Generator) -> np.random.Generator:
    """An independent generator in ``g``'s state: the numbers ``copy.deepcopy(g)`` would draw,
    without its detour through pickling, which seeds a new bit generator from the OS first
    (some 50 us). The copy's seed sequence is a placeholder: nothing spawns from the streams
    copied so (world copies)."""
    bits = g.bit_generator
    new = type(bits)(0)
    new.state = bits.state
    return np.random.Generator(new)
