"""End2End: the NeuroTrajectory body with a classifier head, trained by backpropagation.

The network is the same per-grid CNN -> FC -> FC body (:class:`GridEncoder`) as
NeuroTrajectory's; the features of the newest frame feed two linear heads over the discrete
commands of :mod:`neurotrajectory.data.commands` (21 steering directions 3 degrees apart, and
decelerate / keep / accelerate). It learns, with cross-entropy, the commands the human
set-points imply. Its trajectory is the command's line segment
(:func:`~neurotrajectory.data.commands.command_setpoints`), with each longitudinal class standing
for the median acceleration of its training windows; it is scored by the same metric code as
every other method. In closed loop it drives GridSim-v0 through the discrete action.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import numpy as np
import torch
from pydantic import Field
from torch import nn

from gridsim import libm
from gridsim.outputs import progress_bar, write_json
from neurotrajectory.compare.predictors import Setting, observation_batch
from neurotrajectory.data.commands import (
    LONGITUDINAL,
    N_STEER,
    command_setpoints,
    fit_class_accel,
    steer_angles,
)
from neurotrajectory.data.windows import Windows
from neurotrajectory.model import PRESETS, GridEncoder, NetConfig, one_thread, window_inputs
from neurotrajectory.settings import Integer, Real, Seed, Settings


class End2EndNet(nn.Module):
    """Grids, ego, destination -> (steering logits ``(B, 21)``, longitudinal logits
    ``(B, 3)``), from the body's features of the newest grid (the only frame encoded: the
    body treats each frame alike and apart)."""

    def __init__(self, cfg: NetConfig) -> None:
        super().__init__()
        self.cfg = cfg
        self.encoder = GridEncoder(cfg)
        self.steer = nn.Linear(cfg.fc2, N_STEER)
        self.longitudinal = nn.Linear(cfg.fc2, len(LONGITUDINAL))

    def forward(self, grids, ego, destination):
        feats = self.encoder(grids[:, -1:], ego, destination)[:, 0]
        return self.steer(feats), self.longitudinal(feats)


class TrainSettings(Settings):
    """Supervised training of End2End (Adam, cross-entropy on both heads)."""

    epochs: Annotated[Integer, Field(ge=1)] = Field(
        8, description="training epochs of the End2End baseline"
    )
    batch_size: Annotated[Integer, Field(ge=1)] = Field(32, description="windows per batch")
    learning_rate: Annotated[Real, Field(gt=0)] = Field(1e-3, description="Adam's step size")
    seed: Seed = Field(0, description="seed of the initial weights and the batches' order")


class End2End:
    """A trained End2End network as a predictor."""

    name = "End2End"

    def __init__(self, net: End2EndNet, setting: Setting, class_accel: np.ndarray) -> None:
        self.net = net.eval()
        self.setting = setting
        self.class_accel = np.asarray(class_accel, float)

    @classmethod
    @one_thread()  # (the same bits on any machine; see neurotrajectory.model.one_thread)
    def train(
        cls,
        windows: Windows,
        setting: Setting,
        settings: TrainSettings = TrainSettings(),
        preset: str = "default",
        log=None,
        progress: bool = False,
    ) -> End2End:
        """Fit on ``windows`` (deterministic for a given ``settings.seed``); ``progress``
        shows a bar over the batches of all epochs."""
        if len(windows) == 0:
            raise ValueError("End2End needs at least one training window")
        torch.manual_seed(settings.seed)
        grid = windows.grids.shape[-1]
        base = PRESETS[preset]
        cfg = NetConfig(**{**base.to_dict(), "history": windows.grids.shape[1],
                           "horizon": windows.target.shape[1], "grid_size": grid})  # fmt: skip
        net = End2EndNet(cfg)
        opt = torch.optim.Adam(net.parameters(), lr=settings.learning_rate)
        loss_fn = nn.CrossEntropyLoss()
        steer = torch.from_numpy(windows.steer.astype(np.int64))
        lon = torch.from_numpy(windows.longitudinal.astype(np.int64))
        rng = np.random.default_rng(settings.seed)
        net.train()
        per_epoch = -(-len(windows) // settings.batch_size)
        bar = progress_bar(total=settings.epochs * per_epoch, desc="train End2End",
                           unit="batch", leave=False, disable=not progress)  # fmt: skip
        for epoch in range(settings.epochs):
            order = rng.permutation(len(windows))
            total = 0.0
            bar.set_postfix(epoch=f"{epoch + 1}/{settings.epochs}")
            for start in range(0, len(order), settings.batch_size):
                idx = order[start : start + settings.batch_size]
                s_logits, l_logits = net(*window_inputs(windows, idx))
                loss = loss_fn(s_logits, steer[idx]) + loss_fn(l_logits, lon[idx])
                opt.zero_grad()
                loss.backward()
                opt.step()
                total += loss.item() * len(idx)
                bar.update()
            if log is not None:
                log(f"End2End epoch {epoch + 1}/{settings.epochs}: loss {total / len(order):.3f}")
        bar.close()
        accel = fit_class_accel(windows.longitudinal, windows.accel.astype(float))
        return cls(net, setting, accel)

    @torch.no_grad()
    @one_thread()
    def commands(self, batch: Windows, chunk: int = 256) -> tuple[np.ndarray, np.ndarray]:
        """Predicted (steering class ``(N,)``, longitudinal class ``(N,)``)."""
        steer, lon = [], []
        for start in range(0, len(batch), chunk):
            idx = np.arange(start, min(start + chunk, len(batch)))
            s_logits, l_logits = self.net(*window_inputs(batch, idx))
            steer.append(s_logits.argmax(1).numpy())
            lon.append(l_logits.argmax(1).numpy())
        return np.concatenate(steer), np.concatenate(lon)

    def predict(self, batch: Windows) -> np.ndarray:
        steer, lon = self.commands(batch)
        return command_setpoints(
            steer, lon, batch.speed, batch.heading, self.setting.times, self.class_accel
        )

    # -- persistence ------------------------------------------------------------------------
    def save(self, folder: str | Path) -> None:
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        torch.save(self.net.state_dict(), folder / "end2end.pt")
        meta = {"net": self.net.cfg.to_dict(), "class_accel": self.class_accel.tolist()}
        write_json(folder / "end2end.json", meta)

    @classmethod
    def load(cls, folder: str | Path, setting: Setting) -> End2End:
        folder = Path(folder)
        meta = json.loads((folder / "end2end.json").read_text())
        cfg = meta["net"]
        net = End2EndNet(NetConfig(**{**cfg, "channels": tuple(cfg["channels"])}))
        net.load_state_dict(torch.load(folder / "end2end.pt", weights_only=True))
        return cls(net, setting, np.array(meta["class_accel"]))


class CommandPolicy:
    """End2End driving GridSim-v0 through the discrete action: the predicted direction is
    turned into the steering angle of the arc that reaches it over the horizon; while the
    wheel is more than half a step (1.5 degrees) off it, steer left or right, otherwise
    apply the longitudinal command (keep, accelerate or decelerate)."""

    action_type = "discrete"
    KEEP, ACCELERATE, DECELERATE, LEFT, RIGHT = range(5)

    def __init__(self, model: End2End) -> None:
        self.model = model

    def __call__(self, env, obs, info) -> int:
        batch = observation_batch(obs, env)
        steer, lon = self.model.commands(batch)
        theta = float(steer_angles()[steer[0]])
        wheelbase = float(batch.vehicle[0, 0])
        speed = max(float(batch.speed[0]), 1.0)
        reach = speed * float(self.model.setting.times[-1])
        desired = libm.arctan(wheelbase * 2.0 * theta / reach)  # arc: chord angle = kappa s / 2
        error = desired - float(batch.ego[0, 1])
        half_step = np.deg2rad(1.5)
        if error > half_step:
            return self.LEFT
        if error < -half_step:
            return self.RIGHT
        return (self.DECELERATE, self.KEEP, self.ACCELERATE)[int(lon[0])]


__all__ = ["CommandPolicy", "End2End", "End2EndNet", "TrainSettings"]
