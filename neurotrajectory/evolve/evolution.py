"""Multi-objective neuroevolution (after Such et al. 2017, with NSGA-II selection).

Each generation: sort the population into Pareto fronts by its fitness vectors (minimising
l1 and l2, maximising l3; constrained by the share of episode time lost to collisions and
leaving the road, when given: completing beats any fitness), with crowding distance as
tie-break; carry the first front
(at most ``elite_fraction`` of the population, the least crowded first) over unmodified;
fill the rest with children of tournament-selected parents: uniform crossover of two parents
with probability ``p_crossover``, additive Gaussian mutation (``sigma`` times a slice of the
shared noise table) with probability ``p_mutation``; a child that drew neither is mutated,
so that no evaluation is spent on an exact copy. All draws come from a generator seeded by
(run seed, generation): a run is reproducible and resumable. Generation 0 is drawn the same
way (:func:`initial_recipes`), or around a warm start's genome (:func:`warm_start_recipes`,
from a stream of its own).

**Anchored selection** (``SELECTIONS["anchored"]``, with a warm start): the warm start's genome
stays in every generation as individual 0, the *anchor*, evaluated on the same episodes as
everyone else; a member whose l1 is worse than the anchor's on those episodes violates a
constraint (:func:`anchored_violation`: below any member that kept every episode going,
above any that lost time), and the elites are the first front's members nearest its knee
(not its extremes). Selection then keeps the planner at least as close to the human as the
warm start and searches for members closer still, trading l2 and l3 only among those. The
run keeps the best validated knee of any generation as a candidate for the final front
(:meth:`~neurotrajectory.evolve.runs.Run.finish`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gridsim.seeding import Salt, stream
from neurotrajectory.evolve.genome import Recipe
from neurotrajectory.evolve.pareto import knee_distance, minimised, rank_and_crowding

#: How a generation's parents are selected: ``pareto``, constrained NSGA-II on the three
#: objectives; ``anchored``, the same with the warm start kept as individual 0 and its l1 as
#: a constraint (see the module docstring).
SELECTIONS = ("pareto", "anchored")

#: The anchor's index in every generation of an anchored run.
ANCHOR = 0


def anchored_violation(fitness: np.ndarray, lost: np.ndarray, anchor: int = ANCHOR) -> np.ndarray:
    """The constraint violation of anchored selection: a member that lost episode time
    (``lost`` > 0, the share lost) scores ``1 + lost``, above any that did not; among those,
    a member whose l1 exceeds the anchor's by the share ``x`` scores ``x / (1 + x)`` (in
    [0, 1)), and one no worse than the anchor 0."""
    fitness = np.asarray(fitness, dtype=np.float64)
    lost = np.asarray(lost, dtype=np.float64)
    ref = fitness[anchor, 0]
    excess = np.maximum(fitness[:, 0] - ref, 0.0) / max(abs(ref), 1e-9)
    return np.where(lost > 0, 1.0 + lost, excess / (1.0 + excess))


@dataclass(frozen=True)
class GAConfig:
    population: int = 16
    elite_fraction: float = 0.25
    tournament: int = 2
    p_crossover: float = 0.5
    p_mutation: float = 0.5
    sigma: float = 0.005  # small steps: a network on its prior already drives

    def __post_init__(self) -> None:
        if self.population < 2:
            raise ValueError(f"population must be >= 2, got {self.population}")
        if not 0 < self.elite_fraction < 1:
            raise ValueError(f"elite_fraction must be in (0, 1), got {self.elite_fraction}")
        if self.tournament < 1 or not (0 <= self.p_crossover <= 1 and 0 <= self.p_mutation <= 1):
            raise ValueError("tournament must be >= 1 and probabilities in [0, 1]")
        if not self.sigma > 0:
            raise ValueError(f"sigma must be > 0, got {self.sigma}")


def generation_rng(seed: int, generation: int) -> np.random.Generator:
    """The generator of generation ``generation`` (``-1``: the initial population)."""
    return stream(seed, int(generation) + 1, Salt.GENERATION)


def initial_recipes(config: GAConfig, seed: int) -> list[Recipe]:
    """Generation 0 from random weights: one initial seed per individual."""
    rng = generation_rng(seed, -1)
    return [Recipe(init_seed=int(s)) for s in rng.integers(0, 2**63 - 1, size=config.population)]


def warm_start_recipes(
    config: GAConfig, seed: int, genome_size: int, table_size: int
) -> list[Recipe]:
    """Generation 0 around a warm start's fitted genome (parent 0): itself, then ``sigma``
    mutations of it (noise offsets from their own stream; individual 0's is drawn too)."""
    rng = stream(seed, Salt.WARM_START_MUTATIONS)
    offsets = rng.integers(0, table_size - genome_size, size=config.population)
    mutants = [Recipe(parent=0, noise_offset=int(o), sigma=config.sigma) for o in offsets[1:]]
    return [Recipe(parent=0), *mutants]


def next_generation(
    fitness: np.ndarray,
    config: GAConfig,
    seed: int,
    generation: int,
    genome_size: int,
    table_size: int,
    violation: np.ndarray | None = None,
    anchored: bool = False,
) -> tuple[list[Recipe], np.ndarray]:
    """Recipes of the next population from the fitness ``(K, 3)`` of this one (and its
    constraint ``violation`` ``(K,)``, if any; ``anchored``: the violation of
    :func:`anchored_violation`, and individual :data:`ANCHOR` is carried over as the next
    generation's anchor). Also returns the (constrained) Pareto rank of every individual of
    this generation."""
    k = config.population
    f = minimised(fitness)
    rank, crowd = rank_and_crowding(f, violation)
    rng = generation_rng(seed, generation)
    front = np.flatnonzero(rank == 0)
    cap = max(1, int(round(config.elite_fraction * k)))
    if anchored:
        # the anchor first, then the first front's members nearest its knee
        others = front[front != ANCHOR]
        near = others[np.argsort(knee_distance(f[others]), kind="stable")] if len(others) else []
        elites = [ANCHOR, *near[: cap - 1]]
    else:
        # the first front, least crowded first, capped
        elites = front[np.argsort(-crowd[front], kind="stable")][:cap]
    recipes = [Recipe(parent=int(i)) for i in elites]

    def tournament() -> int:
        cand = rng.integers(0, k, size=config.tournament)
        order = np.lexsort((-crowd[cand], rank[cand]))  # lower rank, then larger crowding
        return int(cand[order[0]])

    max_offset = table_size - genome_size
    while len(recipes) < k:
        a = tournament()
        cross = rng.random() < config.p_crossover
        mutate = rng.random() < config.p_mutation or not cross
        other = tournament() if cross else None
        recipes.append(
            Recipe(
                parent=a,
                other=other,
                crossover_seed=int(rng.integers(0, 2**63 - 1)) if cross else None,
                noise_offset=int(rng.integers(0, max_offset + 1)) if mutate else None,
                sigma=config.sigma if mutate else 0.0,
            )
        )
    return recipes, rank
