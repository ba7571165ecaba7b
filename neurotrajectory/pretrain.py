"""Warm start for neuroevolution: fit the network to recorded human windows first.

Training from random weights leaves the network close to its constant-velocity prior for
many generations. With ``--pretrain DATA``, the run first fits one network by
backpropagation (Adam, mean squared set-point error) to the labelled windows of a dataset
recorded with ``neurotrajectory record`` (:mod:`neurotrajectory.windows`), starting from the
run's NumPy-drawn initial weights; generation 0 is then that network (individual 0) and
mutations of it (``sigma`` times slices of the shared noise table). Deterministic: the same
data and seed give the same weights on this machine (single-threaded torch).
"""

from __future__ import annotations

import numpy as np
import torch

from neurotrajectory.genome import get_genome, set_genome
from neurotrajectory.model import TrajectoryNet, size_mismatch, window_inputs
from neurotrajectory.windows import DatasetError, Windows


class PretrainError(DatasetError):
    """The pre-training data does not fit the network."""


def setpoint_mse(net: TrajectoryNet, windows: Windows, chunk: int = 256) -> float:
    """Mean squared set-point error [m^2] of ``net`` on ``windows``."""
    total = 0.0
    with torch.no_grad():
        for start in range(0, len(windows), chunk):
            idx = np.arange(start, min(start + chunk, len(windows)))
            pred = net(*window_inputs(windows, idx))
            total += float(((pred - torch.from_numpy(windows.target[idx])) ** 2).sum())
    return total / (len(windows) * windows.target.shape[1] * 2)


def pretrain_genome(
    net: TrajectoryNet,
    genome: np.ndarray,
    windows: Windows,
    epochs: int,
    seed: int,
    batch_size: int = 32,
    learning_rate: float = 1e-3,
) -> tuple[np.ndarray, dict]:
    """Fit ``net`` (starting from ``genome``) to ``windows``; returns the new genome and
    ``{"mse_before", "mse_after", "windows", "epochs"}`` [m^2]."""
    problem = size_mismatch(net.cfg, windows)
    if problem:
        raise PretrainError(f"pre-training: {problem}")
    if epochs < 1:
        raise PretrainError(f"pretrain_epochs must be >= 1, got {epochs}")
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        set_genome(net, np.array(genome, dtype=np.float32, copy=True))  # params alias it
        before = setpoint_mse(net, windows)
        opt = torch.optim.Adam(net.parameters(), lr=learning_rate)
        target = torch.from_numpy(windows.target.astype(np.float32))
        rng = np.random.default_rng(np.random.SeedSequence([seed, 0x9E7]))
        net.train()
        for _ in range(epochs):
            order = rng.permutation(len(windows))
            for start in range(0, len(order), batch_size):
                idx = order[start : start + batch_size]
                loss = ((net(*window_inputs(windows, idx)) - target[idx]) ** 2).mean()
                opt.zero_grad()
                loss.backward()
                opt.step()
        net.eval()
        after = setpoint_mse(net, windows)
    finally:
        torch.set_num_threads(threads)
    stats = {"mse_before": before, "mse_after": after, "windows": len(windows), "epochs": epochs}
    return get_genome(net), stats
