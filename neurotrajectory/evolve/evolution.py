"""Multi-objective neuroevolution (after Such et al. 2017, with NSGA-II selection).

Each generation: sort the population into Pareto fronts by its fitness vectors (minimising
l1 and l2, maximising l3; constrained by the share of episode time lost to collisions and
leaving the road, when given: completing beats any fitness), with crowding distance as
tie-break; carry the first front
(at most ``elite_fraction`` of the population, the least crowded first) over unmodified;
fill the rest with children of tournament-selected parents: uniform crossover of two parents
with probability ``p_crossover``, additive Gaussian mutation (``sigma`` times a slice of the
shared noise table) with probability ``p_mutation``; a child that drew neither is mutated, and
so is one whose two tournaments picked the same parent (no crossover: a crossover of a parent
with itself would evaluate an exact copy of it again). All draws come from a generator seeded by
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

**Evolution strategies** (``SELECTIONS["es"]``, with a warm start; after Salimans et al. 2017):
a generation is a *centre* (individual 0, the warm start in generation 0) and antithetic
pairs around it, ``centre + sigma * e`` and ``centre - sigma * e`` (one noise slice per pair,
:func:`es_recipes`), all driven on the same episodes. The next centre moves along the pairs'
differences weighted by their rank-shaped utilities (:func:`es_centre`): every member
contributes, instead of a few lucky ones being copied. The centre's l1 is the anchor's
constraint, as in anchored selection, and its validated score is the learning curve.
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
#: ``es``, evolution strategies around a centre (see the module docstring).
SELECTIONS = ("pareto", "anchored", "es")

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
        if other == a:  # a crossover of a parent with itself is the parent: mutate it instead
            cross, other, mutate = False, None, True
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


def es_recipes(config: GAConfig, rng: np.random.Generator, genome_size: int, table_size: int
               ) -> list[Recipe]:  # fmt: skip
    """A generation of evolution strategies around parent 0 (the centre): the centre itself,
    then antithetic pairs ``+sigma`` and ``-sigma`` times one noise slice each (offsets from
    ``rng``); an odd member left over is one more ``+sigma`` mutation."""
    k = config.population - 1
    offsets = rng.integers(0, table_size - genome_size + 1, size=k - k // 2)
    recipes = [Recipe(parent=0)]
    for o in offsets[: k // 2]:
        recipes += [Recipe(parent=0, noise_offset=int(o), sigma=config.sigma),
                    Recipe(parent=0, noise_offset=int(o), sigma=-config.sigma)]  # fmt: skip
    if k % 2:
        recipes.append(Recipe(parent=0, noise_offset=int(offsets[-1]), sigma=config.sigma))
    return recipes


def es_utilities(fitness: np.ndarray, lost: np.ndarray) -> np.ndarray:
    """Rank-shaped utilities of members ``1..K-1`` (not the centre) in [-0.5, 0.5], the best
    highest: ranked by the episode time they lost, then by l1 (ties in order)."""
    f, lost = np.asarray(fitness, np.float64)[1:], np.asarray(lost, np.float64)[1:]
    order = np.lexsort((f[:, 0], lost))  # best first
    ranks = np.empty(len(f))
    ranks[order] = np.arange(len(f))
    return 0.5 - ranks / max(len(f) - 1, 1)


def es_centre(genomes: np.ndarray, fitness: np.ndarray, lost: np.ndarray, step: float
              ) -> np.ndarray:  # fmt: skip
    """The next centre of a generation made by :func:`es_recipes` (``genomes`` ``(K, n)``,
    their ``fitness`` and lost shares): ``centre + step * mean_j w_j (g+_j - g-_j) / 2``, the
    weight ``w_j`` of pair ``j`` the difference of its members' utilities
    (:func:`es_utilities`), ``(g+ - g-) / 2`` its noise step ``sigma * e``. Accumulated in
    float64 one pair at a time, in order (the same bits on any machine)."""
    u = es_utilities(fitness, lost)
    pairs = (len(genomes) - 1) // 2
    acc = np.zeros(genomes.shape[1], np.float64)
    for j in range(pairs):
        plus, minus = genomes[1 + 2 * j].astype(np.float64), genomes[2 + 2 * j]
        acc += (u[2 * j] - u[2 * j + 1]) * ((plus - minus) / 2.0)
    centre = genomes[0].astype(np.float64) + step * acc / max(pairs, 1)
    return centre.astype(np.float32)
