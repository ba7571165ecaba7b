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

import dataclasses
import hashlib
import io
import json
import math
import time
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
import torch

from gridsim import interrupts
from gridsim.errors import warn_data
from gridsim.outputs import atomic_write, progress_bar
from gridsim.seeding import Salt, stream
from neurotrajectory.data.scratch import concat_windows
from neurotrajectory.data.windows import DatasetError, GridRows, Windows, split_rows
from neurotrajectory.evolve.genome import get_genome, set_genome
from neurotrajectory.model import (
    TrajectoryNet,
    kinematic_features,
    one_thread,
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
    with torch.no_grad(), progress_bar(total=len(windows), desc=progress, unit="window",
                                       leave=False, disable=progress is None) as bar:  # fmt: skip
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


#: Seconds of fitting between saves of the fit inside an epoch (besides each epoch's end and
#: an interrupt between batches): what a fit killed without notice loses at most.
SAVE_SECONDS = 60.0


@dataclass
class _FitState:
    """Where a fit stands: ``epochs`` full epochs and ``batch`` batches of the next done, the
    held-out ``scores`` so far (from the error before the fit), the ``best`` genome, the error
    ``before`` the fit on the fitted windows [m^2] (NaN: not known), and the network's
    ``genome`` and the optimiser's ``optimizer`` state then."""

    epochs: int
    batch: int
    scores: list
    best: np.ndarray
    before: float
    genome: np.ndarray
    optimizer: dict


def _save_fit(path: Path, key: dict, state: _FitState) -> None:
    """``state`` of the fit of ``key``'s inputs, for :func:`_read_fit` (written atomically)."""

    buffer = io.BytesIO()  # tensors and plain values: loaded with weights_only
    torch.save({"key": key, "epochs": state.epochs, "batch": state.batch,
                "genome": torch.from_numpy(state.genome), "optimizer": state.optimizer,
                "scores": [float(v) for v in state.scores],
                "best": torch.from_numpy(np.array(state.best, dtype=np.float32, copy=True)),
                "before": float(state.before)}, buffer)  # fmt: skip

    def write(tmp: str) -> None:  # (written by Python: a full disk is an OSError, said as
        with open(tmp, "wb") as fh:  # such; torch.save's own writer raised a RuntimeError)
            fh.write(buffer.getbuffer())

    atomic_write(path, write)


def _read_fit(path: Path, key: dict, size: int, epochs: int, batches: int) -> _FitState | None:
    """The state of the fit saved in ``path`` (``size`` weights, ``epochs`` epochs of
    ``batches`` batches), once every field was read and checked; None if there is none, or
    one of other inputs or damaged (the fit then starts over). A file saved only at epochs'
    ends, without the batch and the error before the fit, is read too."""
    if not path.is_file():
        return None
    try:
        saved = torch.load(path, weights_only=True)
        if saved["key"] != key:
            return None
        state = _FitState(int(saved["epochs"]), int(saved.get("batch", 0)),
                          [float(v) for v in saved["scores"]], saved["best"].numpy().copy(),
                          float(saved.get("before", math.nan)), saved["genome"].numpy().copy(),
                          saved["optimizer"])  # fmt: skip
    except Exception as exc:  # noqa: BLE001 - a damaged file: the fit starts over, said
        warn_data(f"{path}: the warm start's saved fit cannot be read ({type(exc).__name__}: "
                  f"{str(exc)[:120]}): the fit starts over")  # fmt: skip
        return None
    started = (state.epochs, state.batch) != (0, 0)
    within = 0 <= state.epochs < epochs and 0 <= state.batch <= batches
    if not started or not (within or (state.epochs, state.batch) == (epochs, 0)):
        return None
    if state.genome.shape != (size,) or state.best.shape != (size,):
        return None
    return state


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
    saved after each epoch, every :data:`SAVE_SECONDS` within one, and at a Ctrl-C between
    batches (one arriving inside a batch, in a program that installed
    :func:`gridsim.interrupts.deferred`, waits for the batch's end); a fit of the same inputs
    that was interrupted goes on from there, to the same genome, bit for bit. Removed when
    the fit ends."""
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
    with one_thread():
        set_genome(net, np.array(genome, dtype=np.float32, copy=True))  # params alias it

        def measured(on: Windows, what: str) -> float:  # (with a bar: a pass may take minutes)
            return setpoint_mse(net, on, progress=f"warm start: {what}" if progress else None)

        batches = -(-len(windows) // batch_size)  # per epoch
        saved = None
        if checkpoint is not None:
            key = {"inputs": _fit_inputs(net, genome, windows, held_out, weights),
                   "epochs": epochs, "seed": seed, "batch_size": batch_size,
                   "learning_rate": learning_rate}  # fmt: skip
            size = sum(p.numel() for p in net.parameters())
            saved = _read_fit(checkpoint, key, size, epochs, batches)
        if saved is None or math.isnan(saved.before):
            before = measured(windows, "error before the fit")
        else:
            before = saved.before
        ridge = fit_skip(net, windows, held_out, weights) if net.cfg.skip else {}
        opt = torch.optim.Adam(net.parameters(), lr=learning_rate)
        if saved is not None:  # (its scores begin with the held-out error before the fit)
            set_genome(net, saved.genome)
            opt.load_state_dict(saved.optimizer)
            state = dataclasses.replace(saved, before=before)
        else:
            scores = [measured(held_out, "held-out error")] if held_out is not None else []
            state = _FitState(0, 0, scores, get_genome(net).copy(), before, None, {})
        target = torch.from_numpy(windows.target.astype(np.float32))
        weight = None if weights is None else torch.from_numpy(weights.astype(np.float32))

        def save() -> None:
            if checkpoint is not None:
                state.genome, state.optimizer = get_genome(net).copy(), opt.state_dict()
                _save_fit(checkpoint, key, state)

        def fit_batch(idx: np.ndarray) -> None:
            error = (net(*window_inputs(windows, idx)) - target[idx]) ** 2
            loss = (error if weight is None else error * weight[idx, None, None]).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()

        rng = stream(seed, Salt.WARM_START_BATCHES)
        bar = progress_bar(total=epochs * batches, initial=state.epochs * batches + state.batch,
                           desc="warm start", unit="batch", leave=False,
                           disable=not progress)  # fmt: skip
        consistent, saved_at = True, time.monotonic()  # (not inside a batch's update)
        try:
            for epoch in range(epochs):
                order = rng.permutation(len(windows))  # (drawn for the epochs done before too)
                if epoch < state.epochs:
                    continue
                net.train()
                bar.set_postfix(epoch=f"{epoch + 1}/{epochs}")
                for batch in range(state.batch, batches):
                    interrupts.enter()  # a Ctrl-C waits for the batch's end (then it is saved)
                    try:
                        consistent = False
                        fit_batch(order[batch * batch_size : (batch + 1) * batch_size])
                        state.batch, consistent = batch + 1, True
                    finally:
                        interrupts.leave()
                    bar.update()
                    if time.monotonic() - saved_at > SAVE_SECONDS:
                        save()
                        saved_at = time.monotonic()
                net.eval()
                score = measured(held_out, "held-out error") if held_out is not None else None
                consistent = False  # (the epoch's end: one step for a save)
                if score is not None:
                    if score < min(state.scores):
                        state.best = get_genome(net).copy()
                    state.scores.append(score)
                state.epochs, state.batch, consistent = epoch + 1, 0, True
                save()
                saved_at = time.monotonic()
        except KeyboardInterrupt:  # saved where it stands, if not inside a batch's update
            if consistent and (state.epochs, state.batch) != (0, 0):
                save()
            raise
        finally:
            bar.close()
        if checkpoint is not None:
            checkpoint.unlink(missing_ok=True)
        best, scores = state.best, state.scores
        if held_out is None:
            best = get_genome(net)
        set_genome(net, best.copy())  # the parameters alias what they are set from
        after = measured(windows, "error after the fit")
    stats = {"mse_before": before, "mse_after": after, "windows": len(windows), "epochs": epochs,
             **ridge}  # fmt: skip
    if held_out is not None:
        stats |= {"validation_windows": len(held_out), "validation_mse": scores,
                  "best_epoch": int(np.argmin(scores))}  # fmt: skip
    return best, stats
