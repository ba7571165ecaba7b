"""The NeuroTrajectory network: per-grid CNN -> FC -> FC -> one LSTM branch per set-point.

Input: a GridSim-v0 observation (``grids`` uint8 ``(tau_i, H, W)``, ``ego`` ``(6,)``,
``destination`` ``(2,)``), batched. Output: ``(batch, tau_o, 2)`` set-points [m] in the grid
frame, i.e. directly the environment's trajectory action.

Each grid goes through the same CNN (three stride-2 convolutions); its features, with the
ego state and the destination, go through FC ``fc1`` and FC ``fc2`` (sigmoid by default, as
in the paper). Branch ``i`` is a many-to-one LSTM over the ``tau_i`` per-frame features and
a linear read-out of set-point ``i``. With ``prior="constant_velocity"`` the network predicts
a correction to where the ego would be at constant speed and heading (a residual on a
kinematic prior, so that a freshly initialised network already drives forward).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
import torch
from torch import nn

_ACTIVATIONS = {"sigmoid": nn.Sigmoid, "relu": nn.ReLU, "tanh": nn.Tanh}
DESTINATION_SCALE = 20.0  # m: destination inputs are divided by this


@dataclass(frozen=True)
class NetConfig:
    """Sizes of the network. ``pool`` downsamples the grids before the CNN (1 = none)."""

    history: int = 5
    horizon: int = 5
    grid_size: int = 128
    pool: int = 2
    channels: tuple[int, int, int] = (8, 16, 16)
    fc1: int = 256
    fc2: int = 128
    lstm: int = 32
    activation: str = "sigmoid"
    setpoint_period: float = 0.5
    prior: str = "constant_velocity"

    def __post_init__(self) -> None:
        if self.activation not in _ACTIVATIONS:
            raise ValueError(
                f"activation must be one of {sorted(_ACTIVATIONS)}, got {self.activation!r}"
            )
        if self.prior not in ("constant_velocity", "none"):
            raise ValueError(f"prior must be 'constant_velocity' or 'none', got {self.prior!r}")
        if self.grid_size % (self.pool * 8):
            raise ValueError(
                f"grid_size {self.grid_size} must be divisible by pool * 8 = {self.pool * 8}"
            )

    def to_dict(self) -> dict:
        return asdict(self)


#: ``paper``: the full FC 1024 / 512 on 128 x 128 grids (about 19 M parameters);
#: ``default``: pooled 64 x 64 grids and FC 256 / 128, trains in minutes on 2 CPU cores.
PRESETS = {
    "paper": NetConfig(pool=1, channels=(16, 32, 64), fc1=1024, fc2=512, lstm=128),
    "default": NetConfig(),
    "tiny": NetConfig(pool=4, channels=(4, 8, 8), fc1=32, fc2=32, lstm=8),
}


class BranchLSTMs(nn.Module):
    """``branches`` independent many-to-one LSTMs over the same input sequence, each with a
    linear read-out of one set-point, computed together (batched matrix products; the same
    arithmetic and parameters as separate ``nn.LSTM`` + ``nn.Linear`` modules, faster)."""

    def __init__(self, branches: int, inputs: int, hidden: int) -> None:
        super().__init__()
        k = 1.0 / math.sqrt(hidden)

        def param(*shape):
            return nn.Parameter(torch.empty(*shape).uniform_(-k, k))

        self.hidden = hidden
        self.weight_ih = param(branches, 4 * hidden, inputs)  # gate order i, f, g, o
        self.weight_hh = param(branches, 4 * hidden, hidden)
        self.bias_ih = param(branches, 4 * hidden)
        self.bias_hh = param(branches, 4 * hidden)
        self.head_weight = param(branches, 2, hidden)
        self.head_bias = param(branches, 2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``x`` ``(N, T, inputs)`` -> set-points ``(N, branches, 2)``."""
        n, t, _ = x.shape
        b = self.weight_ih.shape[0]
        bias = (self.bias_ih + self.bias_hh)[:, None, None, :]
        xi = torch.einsum("nti,bgi->btng", x, self.weight_ih) + bias
        h = x.new_zeros(b, n, self.hidden)
        c = x.new_zeros(b, n, self.hidden)
        w_hh = self.weight_hh.transpose(1, 2)
        for step in range(t):
            i, f, g, o = (xi[:, step] + torch.bmm(h, w_hh)).chunk(4, dim=2)
            c = torch.sigmoid(f) * c + torch.sigmoid(i) * torch.tanh(g)
            h = torch.sigmoid(o) * torch.tanh(c)
        out = torch.einsum("bnh,bkh->nbk", h, self.head_weight) + self.head_bias[None]
        return out


class GridEncoder(nn.Module):
    """The network body: each grid through the same CNN, its features with the ego state and
    the destination through FC ``fc1`` and FC ``fc2``. ``(B, tau_i, H, W)`` grids, ``(B, 6)``
    ego, ``(B, 2)`` destination [m] -> per-frame features ``(B, tau_i, fc2)``."""

    def __init__(self, cfg: NetConfig) -> None:
        super().__init__()
        act = _ACTIVATIONS[cfg.activation]
        c1, c2, c3 = cfg.channels
        self.pool = nn.AvgPool2d(cfg.pool) if cfg.pool > 1 else nn.Identity()
        self.cnn = nn.Sequential(
            nn.Conv2d(1, c1, 5, stride=2, padding=2), nn.ReLU(),
            nn.Conv2d(c1, c2, 3, stride=2, padding=1), nn.ReLU(),
            nn.Conv2d(c2, c3, 3, stride=2, padding=1), nn.ReLU(),
            nn.Flatten(),
        )  # fmt: skip
        side = cfg.grid_size // cfg.pool // 8
        n_cnn = c3 * side * side
        self.fc = nn.Sequential(
            nn.Linear(n_cnn + 8, cfg.fc1), act(), nn.Linear(cfg.fc1, cfg.fc2), act()
        )

    def forward(
        self, grids: torch.Tensor, ego: torch.Tensor, destination: torch.Tensor
    ) -> torch.Tensor:
        b, t, h, w = grids.shape
        x = grids.reshape(b * t, 1, h, w).float() / 255.0
        feats = self.cnn(self.pool(x)).reshape(b, t, -1)
        side = torch.cat([ego, destination / DESTINATION_SCALE], dim=1)
        return self.fc(torch.cat([feats, side[:, None, :].expand(b, t, side.shape[1])], dim=2))


def constant_velocity_setpoints(ego: torch.Tensor, times: torch.Tensor) -> torch.Tensor:
    """Where the ego would be at ``times`` [s] holding its speed and heading: ``(B, T, 2)`` [m,
    grid frame] from ``ego`` ``(B, 6)`` (speed, ..., cos, sin of the heading)."""
    speed, cos, sin = ego[:, 0:1], ego[:, 4:5], ego[:, 5:6]
    dist = speed * times[None, :]
    return torch.stack([dist * cos, dist * sin], dim=2)


class TrajectoryNet(nn.Module):
    """See the module docstring."""

    def __init__(self, cfg: NetConfig) -> None:
        super().__init__()
        self.cfg = cfg
        self.encoder = GridEncoder(cfg)
        self.branches = BranchLSTMs(cfg.horizon, cfg.fc2, cfg.lstm)
        times = cfg.setpoint_period * torch.arange(1, cfg.horizon + 1, dtype=torch.float32)
        self.register_buffer("times", times, persistent=False)

    def forward(
        self, grids: torch.Tensor, ego: torch.Tensor, destination: torch.Tensor
    ) -> torch.Tensor:
        """``grids`` uint8 or float ``(B, tau_i, H, W)``; ``ego`` ``(B, 6)``; ``destination``
        ``(B, 2)`` [m]. Returns set-points ``(B, tau_o, 2)`` [m]."""
        out = self.branches(self.encoder(grids, ego, destination))
        if self.cfg.prior == "constant_velocity":
            out = out + constant_velocity_setpoints(ego, self.times)
        return out


def observation_tensors(obs: dict | list[dict]) -> tuple[torch.Tensor, ...]:
    """Batch GridSim-v0 observations (one dict or a list) into the network's inputs."""
    if isinstance(obs, dict):
        obs = [obs]
    grids = torch.from_numpy(np.stack([o["grids"] for o in obs]))
    ego = torch.from_numpy(np.stack([o["ego"] for o in obs]).astype(np.float32))
    dest = torch.from_numpy(np.stack([o["destination"] for o in obs]).astype(np.float32))
    return grids, ego, dest


def count_parameters(net: nn.Module) -> int:
    return sum(p.numel() for p in net.parameters())


def window_inputs(windows, index: np.ndarray) -> tuple[torch.Tensor, ...]:
    """The network's inputs for ``windows[index]`` (a :class:`~neurotrajectory.windows.Windows`
    batch): grids, ego state and destination tensors."""
    return (
        torch.from_numpy(windows.grids[index]),
        torch.from_numpy(windows.ego[index].astype(np.float32)),
        torch.from_numpy(windows.destination[index].astype(np.float32)),
    )


def size_mismatch(cfg: NetConfig, windows) -> str | None:
    """Why ``windows`` cannot feed a network of ``cfg``, or None if they can."""
    got = (windows.grids.shape[1], windows.grids.shape[2], windows.target.shape[1])
    want = (cfg.history, cfg.grid_size, cfg.horizon)
    if got == want:
        return None
    return (
        f"the windows have (history, grid size, horizon) = {got}, the network needs {want}: "
        "record them from a scenario with the same env and sensor sizes"
    )
