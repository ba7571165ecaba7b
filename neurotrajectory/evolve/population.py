"""The population: one generation's genomes, and the one way each generation is made.

A :class:`Population` owns the genomes of the current generation (64-byte aligned rows, as
the batched forward pass wants them) and the shared noise table they are mutated with. It
is replaced by the children of a list of recipes (:meth:`Population.advance`), or by given
genomes (:meth:`Population.load`). Every worker holds one; the trainer reads its backend's
(:attr:`~neurotrajectory.evolve.backends.Backend.population`) to checkpoint it.

Every generation a run evaluates is made the same way: recipes applied to parents. A
:class:`Start` names the first one and where it comes from (:class:`Source`): generation 0
from random weights (recipes with initial seeds, no parents), generation 0 around a warm
start's fitted genome (one parent), or the generation after a checkpoint's (its genomes).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np
from torch import nn

from neurotrajectory.evolve.genome import (
    Recipe,
    apply_recipe,
    initial_genome,
    mutation_mask,
    noise_table,
    table_size,
)
from neurotrajectory.model import aligned_rows, count_parameters


class Population:
    """One generation's genomes ``(K, n)`` and the noise table its children are mutated with;
    ``net`` gives the genome's layout (initial genomes are drawn for it); mutation changes
    the parameters ``net.evolved(evolve)`` names (see :data:`~neurotrajectory.model.EVOLVE_SCOPES`),
    the others pass from parents to children unchanged."""

    def __init__(self, net: nn.Module, evolve: str = "all") -> None:
        self.net = net
        self.genome_size = count_parameters(net)
        self.table = noise_table(table_size(self.genome_size))
        self.mask = None if evolve == "all" else mutation_mask(net, net.evolved(evolve))
        self.genomes: np.ndarray | None = None

    def advance(self, recipes: list[Recipe]) -> None:
        """Replace the genomes by the children of ``recipes``."""
        children = [
            apply_recipe(r, self.genomes, self.table,
                         initial_genome(self.net, r.init_seed) if r.init_seed is not None else None,
                         self.mask)
            for r in recipes
        ]  # fmt: skip
        self.load(children)

    def load(self, genomes) -> None:
        """Hold a copy of ``genomes`` (rows aligned for the batched forward pass)."""
        rows = aligned_rows(len(genomes), self.genome_size).numpy()
        for i, genome in enumerate(genomes):
            rows[i] = genome
        self.genomes = rows


class Source(Enum):
    """Where a run's first evaluated generation comes from."""

    RANDOM = "random weights"
    WARM_START = "a warm start"
    CHECKPOINT = "a checkpoint"


@dataclass(frozen=True)
class Start:
    """The first generation a run evaluates: ``generation``, the children of ``recipes`` from
    ``parents`` (None: generation 0 from random weights)."""

    generation: int
    recipes: list[Recipe]
    parents: np.ndarray | None = None
