"""Warm start for neuroevolution: fit the network to recorded human windows first.

Training from random weights leaves the network close to its constant-velocity prior for
many generations. With ``--pretrain DATA``, the run first fits one network by
backpropagation (Adam, mean squared set-point error) to the labelled windows of a dataset
recorded with ``neurotrajectory record`` (:mod:`neurotrajectory.data.windows`), starting from the
run's NumPy-drawn initial weights; generation 0 is then that network (individual 0) and
mutations of it (``sigma`` times slices of the shared noise table). With ``validation`` > 0
that share of the tracks is held out of the fit and the epoch whose weights predict them
best is kept (epoch 0, the untrained network, included): the fit never ends worse than the
prior on tracks it did not see. Deterministic: the same data and seed give the same weights
on this machine (single-threaded torch).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import fields
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from gridsim.outputs import atomic_write
from gridsim.seeding import Salt, stream
from neurotrajectory.data.scratch import concat_windows
from neurotrajectory.data.windows import DatasetError, GridRows, Windows, split_rows
from neurotrajectory.evolve.genome import get_genome, set_genome
from neurotrajectory.model import (
    TrajectoryNet,
    kinematic_features,
    prior_setpoints,
    size_mismatch,
    to_ego_frame,
    window_inputs,
)


class PretrainError(DatasetError):
    """The pre-training data does not fit the network."""


def setpoint_mse(
    net: TrajectoryNet, windows: Windows, chunk: int = 256, progress: str | None = None
) -> float:
    """Mean squared set-point error [m^2] of ``net`` on ``windows``; ``progress``: a bar of
    that description over the windows (a pass over many takes minutes)."""
    total = 0.0
    with torch.no_grad(), tqdm(total=len(windows), desc=progress, unit="window", leave=False,
                               disable=progress is None) as bar:  # fmt: skip
        for start in range(0, len(windows), chunk):
            idx = np.arange(start, min(start + chunk, len(windows)))
            pred = net(*window_inputs(windows, idx))
            total += float(((pred - torch.from_numpy(windows.target[idx])) ** 2).sum())
            bar.update(len(idx))
    return total / (len(windows) * windows.target.shape[1] * 2)


#: Ridge penalties tried for the skip read-out (on standardised features, per window).
RIDGE_PENALTIES = (1e-3, 1e-2, 1e-1, 1.0, 10.0)


def _skip_problem(net: TrajectoryNet, windows: Windows) -> tuple[np.ndarray, np.ndarray]:
    """The skip read-out's inputs ``(N, F)`` and what it should output ``(N, tau_o * 2)``: the
    human set-points minus the prior's, in the residual's frame."""
    ego = torch.from_numpy(windows.ego.astype(np.float32))
    dest = torch.from_numpy(windows.destination.astype(np.float32))
    prior = prior_setpoints(net.cfg, ego, dest, net.times)
    residual = torch.from_numpy(windows.target.astype(np.float32))
    if prior is not None:
        residual = residual - prior
    if net.cfg.frame == "ego":
        residual = to_ego_frame(residual, ego)
    feats = kinematic_features(net.cfg, ego, dest, prior)
    return feats.double().numpy(), residual.reshape(len(windows), -1).double().numpy()


def fit_skip(
    net: TrajectoryNet, fit: Windows, held_out: Windows | None, weights: np.ndarray | None = None
) -> dict:
    """Set the skip read-out (and the branches' output bias) to the ridge regression of the
    residual on the kinematic features over ``fit`` (each window weighted by ``weights``, none:
    alike), the penalty chosen on ``held_out`` (the smallest of :data:`RIDGE_PENALTIES` without
    it); the branches' read-out weights must be 0. Returns ``{"ridge_penalty",
    "ridge_validation_mse"}``."""
    x, y = _skip_problem(net, fit)
    mu = np.average(x, axis=0, weights=weights)
    sd = np.sqrt(np.average((x - mu) ** 2, axis=0, weights=weights))
    sd = np.where(sd > 1e-9, sd, 1.0)
    z = (x - mu) / sd
    ym = np.average(y, axis=0, weights=weights)
    wz = z if weights is None else z * weights[:, None]
    gram, rhs = wz.T @ z, wz.T @ (y - ym)
    total = len(z) if weights is None else float(weights.sum())
    best = None
    for penalty in RIDGE_PENALTIES if held_out is not None else RIDGE_PENALTIES[:1]:
        coef = np.linalg.solve(gram + penalty * total * np.eye(len(gram)), rhs) / sd[:, None]
        bias = ym - mu @ coef
        score = None
        if held_out is not None:
            xv, yv = _skip_problem(net, held_out)
            score = float(np.mean((xv @ coef + bias - yv) ** 2))
        if best is None or score < best[0]:
            best = (score, penalty, coef, bias)
    score, penalty, coef, bias = best
    horizon = net.cfg.horizon
    with torch.no_grad():
        net.skip_weight.copy_(torch.from_numpy(coef.T.reshape(horizon, 2, -1)))
        net.branches.head_bias.copy_(torch.from_numpy(bias.reshape(horizon, 2)))
    return {"ridge_penalty": penalty, "ridge_validation_mse": score}


def _save_fit(path: Path, key: dict, epochs: int, net, opt, scores: list, best) -> None:
    """The fit after ``epochs`` epochs, for :func:`_load_fit` (written atomically)."""

    def write(tmp: str) -> None:  # tensors and plain values: loaded with weights_only
        torch.save({"key": key, "epochs": epochs,
                    "genome": torch.from_numpy(get_genome(net).copy()),
                    "optimizer": opt.state_dict(), "scores": [float(v) for v in scores],
                    "best": torch.from_numpy(np.array(best, dtype=np.float32, copy=True))},
                   tmp)  # fmt: skip

    atomic_write(path, write)


def _load_fit(path: Path, key: dict, net, opt, epochs: int) -> tuple[int, list, np.ndarray] | None:
    """``(epochs done, validation scores, best genome)`` of the fit saved in ``path``, with
    ``net`` and ``opt`` set as they were then (only once every field was read and checked);
    None if there is none, or one of other inputs or damaged (the fit then starts over)."""
    if not path.is_file():
        return None
    size = sum(p.numel() for p in net.parameters())
    try:
        saved = torch.load(path, weights_only=True)
        if saved["key"] != key:
            return None
        done, scores = int(saved["epochs"]), [float(v) for v in saved["scores"]]
        weights, best = saved["genome"].numpy().copy(), saved["best"].numpy().copy()
        state = saved["optimizer"]
        if not 0 < done <= epochs or weights.shape != (size,) or best.shape != (size,):
            return None
    except Exception:  # noqa: BLE001 - a damaged file: the fit starts over
        return None
    set_genome(net, weights)
    opt.load_state_dict(state)
    return done, scores, best


def _fit_inputs(net, genome, windows: Windows, held_out, weights) -> str:
    """A digest of what a fit starts from: the network's configuration, the start genome,
    every array of the fitted and held-out windows (the grids read in place) and the
    windows' weights."""
    h = hashlib.blake2b(digest_size=16)
    h.update(json.dumps(net.cfg.to_dict(), sort_keys=True).encode())
    h.update(np.ascontiguousarray(genome, dtype=np.float32).tobytes())
    hashed: list[np.ndarray] = []  # the grids both sides select from: read once
    for part in (windows, held_out):
        if part is None:
            h.update(b"none")
            continue
        for f in fields(part):
            value = getattr(part, f.name)
            if isinstance(value, GridRows):
                h.update(value.rows.tobytes())
                if any(value.base is seen for seen in hashed):
                    continue
                hashed.append(value.base)
                value = value.base
            h.update(memoryview(np.ascontiguousarray(value)).cast("B"))
    h.update(b"none" if weights is None else np.ascontiguousarray(weights).tobytes())
    return h.hexdigest()


def visited_weights(human: int, visited: int, share: float | None) -> np.ndarray | None:
    """Per-window weights (mean 1) of ``human`` human windows followed by ``visited`` visited
    ones (DAgger): each human window weighs 1 and the visited windows together ``share`` times
    the human windows' total. None (every window alike) if ``share`` is None or there is no
    visited window."""
    if share is None or not visited:
        return None
    weights = np.concatenate([np.ones(human), np.full(visited, share * human / visited)])
    return weights / weights.mean()


def pretrain_genome(
    net: TrajectoryNet,
    genome: np.ndarray,
    windows: Windows,
    epochs: int,
    seed: int,
    batch_size: int = 32,
    learning_rate: float = 1e-3,
    validation: float = 0.0,
    visited: Windows | None = None,
    visited_share: float | None = None,
    progress: bool = False,
    checkpoint: Path | None = None,
) -> tuple[np.ndarray, dict]:
    """Fit ``net`` (starting from ``genome``) to ``windows``, holding out ``validation`` of
    the tracks to pick the epoch (see the module docstring); returns the new genome and
    ``{"mse_before", "mse_after", "windows", "epochs"}`` [m^2] (on the fitted windows), with
    ``validation_mse`` per epoch (from 0), ``best_epoch`` and ``validation_windows``.

    ``visited`` (DAgger: the states the network drove to, labelled with the human's next
    set-points) are fitted too, weighted by :func:`visited_weights` with ``visited_share``, but
    never validated on: the epoch is picked on the held-out tracks' human windows, and the
    visited windows of those tracks are left out. ``progress``: a bar over the batches of
    all epochs (with each epoch's validation error). ``checkpoint``: a file where the fit is
    saved after each epoch, and from which a fit of the same inputs that was interrupted
    goes on (to the same genome, bit for bit); removed when the fit ends."""
    problem = size_mismatch(net.cfg, windows)
    if problem:
        raise PretrainError(f"pre-training: {problem}")
    if epochs < 1:
        raise PretrainError(f"pretrain_epochs must be >= 1, got {epochs}")
    held_out = None
    if validation > 0:
        if len(np.unique(windows.track)) < 2:
            raise PretrainError(
                "pre-training: a validation share needs windows of >= 2 tracks, got "
                f"{len(np.unique(windows.track))}; record more episodes or set it to 0"
            )
        # (the grids are read from the dataset's as batches ask for them, not copied)
        windows, held_out = (windows.select(rows) for rows in split_rows(windows, validation,
                                                                         seed))  # fmt: skip
    weights = None
    if visited is not None and len(visited):
        if held_out is not None:
            visited = visited.take(np.flatnonzero(~np.isin(visited.track, held_out.track)))
        weights = visited_weights(len(windows), len(visited), visited_share)
        windows = concat_windows([windows, visited], "the warm start's windows")
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        set_genome(net, np.array(genome, dtype=np.float32, copy=True))  # params alias it

        def measured(on: Windows, what: str) -> float:  # (with a bar: a pass may take minutes)
            return setpoint_mse(net, on, progress=f"warm start: {what}" if progress else None)

        before = measured(windows, "error before the fit")
        ridge = fit_skip(net, windows, held_out, weights) if net.cfg.skip else {}
        opt = torch.optim.Adam(net.parameters(), lr=learning_rate)
        done = None
        if checkpoint is not None:
            key = {"inputs": _fit_inputs(net, genome, windows, held_out, weights),
                   "epochs": epochs, "seed": seed, "batch_size": batch_size,
                   "learning_rate": learning_rate}  # fmt: skip
            done = _load_fit(checkpoint, key, net, opt, epochs)
        if done is not None:  # (its scores begin with the held-out error before the fit)
            first, scores, best = done
        else:
            first = 0
            scores = [measured(held_out, "held-out error")] if held_out is not None else []
            best = get_genome(net).copy()
        target = torch.from_numpy(windows.target.astype(np.float32))
        weight = None if weights is None else torch.from_numpy(weights.astype(np.float32))
        rng = stream(seed, Salt.WARM_START_BATCHES)
        batches = -(-len(windows) // batch_size)  # per epoch
        bar = tqdm(total=epochs * batches, initial=first * batches, desc="warm start",
                   unit="batch", leave=False, disable=not progress)  # fmt: skip
        for epoch in range(epochs):
            order = rng.permutation(len(windows))  # (drawn for the epochs done before too)
            if epoch < first:
                continue
            net.train()
            bar.set_postfix(epoch=f"{epoch + 1}/{epochs}")
            for start in range(0, len(order), batch_size):
                idx = order[start : start + batch_size]
                error = (net(*window_inputs(windows, idx)) - target[idx]) ** 2
                loss = (error if weight is None else error * weight[idx, None, None]).mean()
                opt.zero_grad()
                loss.backward()
                opt.step()
                bar.update()
            net.eval()
            if held_out is not None:
                scores.append(measured(held_out, "held-out error"))
                if scores[-1] < min(scores[:-1]):
                    best = get_genome(net).copy()
            if checkpoint is not None:
                _save_fit(checkpoint, key, epoch + 1, net, opt, scores, best)
        bar.close()
        if checkpoint is not None:
            checkpoint.unlink(missing_ok=True)
        if held_out is None:
            best = get_genome(net)
        set_genome(net, best.copy())  # the parameters alias what they are set from
        after = measured(windows, "error after the fit")
    finally:
        torch.set_num_threads(threads)
    stats = {"mse_before": before, "mse_after": after, "windows": len(windows), "epochs": epochs,
             **ridge}  # fmt: skip
    if held_out is not None:
        stats |= {"validation_windows": len(held_out), "validation_mse": scores,
                  "best_epoch": int(np.argmin(scores))}  # fmt: skip
    return best, stats
