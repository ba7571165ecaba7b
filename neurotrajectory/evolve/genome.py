"""Genomes: a network's weights as one flat float32 vector, a shared noise table, recipes.

Mutation noise is read from a table of standard normal float32 numbers generated once by
NumPy's PCG64 from a fixed seed: the same bits on every machine (``torch.randn`` is not
bit-identical across CPU kernels). A child is described by a small :class:`Recipe`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import torch
from torch import nn

from gridsim.seeding import Salt
from neurotrajectory.model import count_parameters


@lru_cache(maxsize=2)
def noise_table(size: int) -> np.ndarray:
    """``size`` standard normal float32 numbers (read-only), identical on every machine."""
    table = np.random.default_rng(int(Salt.NOISE_TABLE)).standard_normal(size, dtype=np.float32)
    table.flags.writeable = False
    return table


def table_size(n_params: int) -> int:
    """A table at least twice the genome length (and at least 2^22), a power of two."""
    return 1 << max(22, int(np.ceil(np.log2(2 * n_params))))


def get_genome(net: nn.Module) -> np.ndarray:
    return torch.nn.utils.parameters_to_vector(net.parameters()).detach().numpy().astype(np.float32)


def genome_mismatch(net: nn.Module, size: int) -> str | None:
    """Why genomes of ``size`` weights do not fit ``net``, or None if they do."""
    n = count_parameters(net)
    if size == n:
        return None
    return (f"genomes of {size} weights, the network has {n}: saved with another preset, "
            "prior, frame or scenario")  # fmt: skip


def set_genome(net: nn.Module, genome: np.ndarray) -> None:
    problem = genome_mismatch(net, np.shape(genome)[-1] if np.ndim(genome) else 0)
    if problem:
        raise ValueError(problem)
    vec = torch.from_numpy(np.ascontiguousarray(genome, dtype=np.float32))
    torch.nn.utils.vector_to_parameters(vec, net.parameters())


def mutation_mask(net: nn.Module, evolved: tuple[str, ...] | None) -> np.ndarray | None:
    """A float32 0/1 vector over the genome: 1 where a parameter named in ``evolved`` lies
    (None: every weight evolves, no mask)."""
    if evolved is None:
        return None
    unknown = set(evolved) - {name for name, _ in net.named_parameters()}
    if unknown:
        raise ValueError(f"the network has no parameters {sorted(unknown)}")
    if not evolved:
        raise ValueError("no parameter to evolve: every child would equal its parent")
    return np.concatenate([np.full(p.numel(), name in evolved, np.float32)
                           for name, p in net.named_parameters()])  # fmt: skip


def initial_genome(net: nn.Module, seed: int) -> np.ndarray:
    """Weights ~ N(0, 1 / fan_in), biases 0, drawn with NumPy from ``seed`` (reproducible
    everywhere, unlike torch's initialisers); the parameters the network names in its
    ``zero_init`` (if any) start at 0."""
    rng = np.random.default_rng(seed)
    zero = set(getattr(net, "zero_init", ()))
    parts = []
    for name, p in net.named_parameters():
        if "bias" in name or name in zero:
            parts.append(np.zeros(p.numel(), np.float32))
            continue
        # Convolutions (out, in, k, k): in * k * k; matrices (..., out, in): in.
        fan_in = int(np.prod(p.shape[1:])) if p.dim() == 4 else int(p.shape[-1])
        parts.append(
            (rng.standard_normal(p.numel(), dtype=np.float32) / np.sqrt(fan_in)).astype(np.float32)
        )
    return np.concatenate(parts)


@dataclass(frozen=True)
class Recipe:
    """How to build one individual from the previous generation's population.

    ``parent``: index of the first parent (the individual itself for an elite);
    ``other`` and ``crossover_seed``: uniform crossover with a second parent (each weight
    from ``other`` with probability 1/2, drawn from ``crossover_seed``);
    ``noise_offset`` and ``sigma``: additive Gaussian mutation ``sigma * table[offset:]``.
    Generation 0 individuals have ``init_seed`` instead of parents.
    """

    parent: int = -1
    other: int | None = None
    crossover_seed: int | None = None
    noise_offset: int | None = None
    sigma: float = 0.0
    init_seed: int | None = None

    @property
    def is_elite(self) -> bool:
        return self.init_seed is None and self.other is None and self.noise_offset is None


def apply_recipe(
    recipe: Recipe,
    parents: np.ndarray | None,
    table: np.ndarray,
    init: np.ndarray | None = None,
    mask: np.ndarray | None = None,
) -> np.ndarray:
    """The child genome of ``recipe``. ``parents`` ``(K, n)``; ``init`` is the genome made
    from ``recipe.init_seed`` (generation 0); ``mask`` (:func:`mutation_mask`) limits the
    mutation to the evolved weights."""
    if recipe.init_seed is not None:
        child = np.array(init, dtype=np.float32, copy=True)
    else:
        child = parents[recipe.parent].copy()
    n = len(child)
    if recipe.other is not None:
        from_other = np.random.default_rng(recipe.crossover_seed).random(n) < 0.5
        child[from_other] = parents[recipe.other][from_other]
    if recipe.noise_offset is not None:
        noise = np.float32(recipe.sigma) * table[recipe.noise_offset : recipe.noise_offset + n]
        child += noise if mask is None else noise * mask
    return child
