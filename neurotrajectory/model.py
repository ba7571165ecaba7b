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


# -- population forward -----------------------------------------------------------------------
#
# ``PopulationNet`` evaluates the TrajectoryNet of many individuals at once, each with its own
# weights, for a fixed number ``E`` of environments per individual. The arithmetic of one
# individual never depends on which or how many other individuals are in the batch:
#
# * every matrix product is a ``torch.bmm`` item with a fixed shape per individual (convs:
#   one item per (individual, env, frame), fully connected layers: one item per individual
#   with all ``E`` rows, dead environments included); MKL computes each item alike
#   whatever the batch (the rows of one item are NOT independent of the item's row count,
#   hence the fixed ``E``);
# * the element-wise functions are exact (add, mul, relu) or computed the same at every
#   position of a tensor (``exp`` and ``tanh`` go through vectorised kernels with masked
#   tails); ``torch.sigmoid`` is not (its scalar tail loop rounds differently), so the
#   sigmoid is ``1 / (1 + exp(-x))``;
# * average pooling sums the uint8 cells exactly and divides once.
#
# The result differs from :class:`TrajectoryNet` by float rounding only (about 1e-6 m on the
# set-points; asserted in the tests). Training and its fitness use this path only.

_CONVS = ((5, 2, 2), (3, 2, 1), (3, 2, 1))  # kernel, stride, padding of GridEncoder.cnn
_CONV_NAMES = ("encoder.cnn.0", "encoder.cnn.2", "encoder.cnn.4")
#: Weight matrices of at least this many numbers are never copied: products with them run
#: on views into the population, one ``bmm`` per run of consecutive individuals.
BIG_PARAMETER = 1 << 19


def _sigmoid(x: torch.Tensor) -> torch.Tensor:
    return torch.reciprocal(torch.exp(-x).add_(1.0))


def _tanh(x: torch.Tensor) -> torch.Tensor:
    return torch.tanh(x)


_PW_ACTIVATIONS = {"sigmoid": _sigmoid, "relu": torch.relu, "tanh": _tanh}


def _bmm_t(x: torch.Tensor, w) -> torch.Tensor:
    """``x`` ``(K, M, in)`` times the transpose of ``w`` ``(K, out, in)`` per individual; ``w``
    may be a list of views ``(K_i, out, in)`` covering the K individuals in order."""
    if isinstance(w, torch.Tensor):
        return torch.bmm(x, w.transpose(1, 2))
    outs, a = [], 0
    for part in w:
        b = a + part.shape[0]
        outs.append(torch.bmm(x[a:b], part.transpose(1, 2)))
        a = b
    return outs[0] if len(outs) == 1 else torch.cat(outs)


class PopulationNet:
    """The forward pass of :class:`TrajectoryNet` for a batch of individuals (see above)."""

    def __init__(self, cfg: NetConfig) -> None:
        self.cfg = cfg
        template = TrajectoryNet(cfg)
        self.shapes: dict[str, tuple[int, ...]] = {}
        self.offsets: dict[str, int] = {}
        off = 0
        for name, p in template.named_parameters():
            self.shapes[name], self.offsets[name] = tuple(p.shape), off
            off += p.numel()
        self.size = off
        c3 = cfg.channels[2]
        self.side = cfg.grid_size // cfg.pool // 8
        self.n_cnn = c3 * self.side * self.side
        self.times = template.times.clone()
        self.act = _PW_ACTIVATIONS[cfg.activation]
        self.big_parameter = BIG_PARAMETER

    # -- parameters ---------------------------------------------------------------------------
    def view(self, population: torch.Tensor, name: str) -> torch.Tensor:
        """Parameter ``name`` of every row of ``population`` ``(K, n)``: a view ``(K, *shape)``."""
        off, shape = self.offsets[name], self.shapes[name]
        n = math.prod(shape)
        return population[:, off : off + n].view(population.shape[0], *shape)

    def params(self, population: torch.Tensor, rows: np.ndarray) -> dict:
        """The parameters of individuals ``rows`` of ``population``: small ones gathered into
        ``(len(rows), ...)`` tensors, big weight matrices as lists of views (runs of
        consecutive rows)."""
        everyone = len(rows) == population.shape[0]
        runs = np.split(rows, np.flatnonzero(np.diff(rows) != 1) + 1)
        index = torch.from_numpy(np.asarray(rows, dtype=np.int64))
        out = {}
        for name, shape in self.shapes.items():
            full = self.view(population, name)
            if name == "branches.weight_ih":  # used as one (branches * 4h, fc2) matrix
                full = full.reshape(full.shape[0], shape[0] * shape[1], shape[2])
            if math.prod(shape) >= self.big_parameter and full.dim() == 3:
                out[name] = [full[r[0] : r[-1] + 1] for r in runs]
            else:
                out[name] = full if everyone else full.index_select(0, index)
        return out

    # -- the forward pass, in three parts -----------------------------------------------------
    def frame_features(self, params: dict, owner: torch.Tensor, frames: np.ndarray):
        """CNN features ``(N, n_cnn)`` of ``frames`` uint8 ``(N, H, W)``; frame ``i`` belongs to
        individual ``owner[i]`` (an index into ``params``)."""
        p = self.cfg.pool
        x = torch.from_numpy(frames)
        n, h, w = x.shape
        if p > 1:  # exact integer sums, one rounding
            x = x.view(n, h // p, p, w // p, p).sum(dim=(2, 4), dtype=torch.int32)
        x = (x.float() / float(255 * p * p))[:, None]
        for (k, stride, pad), name in zip(_CONVS, _CONV_NAMES, strict=True):
            weight = params[name + ".weight"].index_select(0, owner)
            bias = params[name + ".bias"].index_select(0, owner)
            side = (x.shape[2] + 2 * pad - k) // stride + 1
            cols = torch.nn.functional.unfold(x, k, padding=pad, stride=stride)
            y = torch.bmm(weight.reshape(n, weight.shape[1], -1), cols) + bias[:, :, None]
            x = torch.relu(y).view(n, weight.shape[1], side, side)
        return x.reshape(n, -1)

    def grid_part(self, params: dict, feats: torch.Tensor) -> torch.Tensor:
        """``fc1``'s product with the CNN features of one frame: ``feats`` ``(K, E, n_cnn)`` ->
        ``(K, E, fc1)``."""
        w = params["encoder.fc.0.weight"]
        n = self.n_cnn
        w = w[:, :, :n] if isinstance(w, torch.Tensor) else [v[:, :, :n] for v in w]
        return _bmm_t(feats, w)

    def head(self, params: dict, grid: torch.Tensor, ego: torch.Tensor, dest: torch.Tensor):
        """Set-points ``(K, E, tau_o, 2)`` from ``grid`` ``(K, E, tau_i, fc1)`` (the frames'
        :meth:`grid_part`, oldest first), ``ego`` ``(K, E, 6)`` and ``dest`` ``(K, E, 2)`` [m]."""
        k, e, t, _ = grid.shape
        n = self.n_cnn
        w1 = params["encoder.fc.0.weight"]
        w1s = w1[:, :, n:] if isinstance(w1, torch.Tensor) else [v[:, :, n:] for v in w1]
        side = torch.cat([ego, dest / DESTINATION_SCALE], dim=2)
        side = _bmm_t(side, w1s) + params["encoder.fc.0.bias"][:, None, :]
        a1 = self.act(grid + side[:, :, None, :])
        a2 = _bmm_t(a1.reshape(k, e * t, -1), params["encoder.fc.2.weight"])
        a2 = self.act(a2 + params["encoder.fc.2.bias"][:, None, :])
        # the branches: xi (K, E*T, B*4h) -> (K, B, T, E, 4h)
        b, g4, hid = self.shapes["branches.weight_hh"]
        xi = _bmm_t(a2, params["branches.weight_ih"]).view(k, e, t, b, g4)
        bias = (params["branches.bias_ih"] + params["branches.bias_hh"])[:, None, None]
        xi = (xi + bias).permute(0, 3, 2, 1, 4).contiguous()
        w_hh = params["branches.weight_hh"].reshape(k * b, g4, hid).transpose(1, 2)
        h = grid.new_zeros(k * b, e, hid)
        c = grid.new_zeros(k * b, e, hid)
        for step in range(t):
            gates = xi[:, :, step].reshape(k * b, e, g4) + torch.bmm(h, w_hh)
            i, f, g, o = gates.chunk(4, dim=2)
            c = _sigmoid(f) * c + _sigmoid(i) * torch.tanh(g)
            h = _sigmoid(o) * torch.tanh(c)
        w_head = params["branches.head_weight"].reshape(k * b, 2, hid).transpose(1, 2)
        out = torch.bmm(h, w_head).view(k, b, e, 2) + params["branches.head_bias"][:, :, None]
        out = out.permute(0, 2, 1, 3)
        if self.cfg.prior == "constant_velocity":
            cv = constant_velocity_setpoints(ego.reshape(k * e, 6), self.times)
            out = out + cv.view(k, e, b, 2)
        return out

    def forward(self, population: torch.Tensor, grids, ego, dest) -> torch.Tensor:
        """Everything at once (no caching): ``population`` ``(K, n)``, ``grids`` uint8
        ``(K, E, tau_i, H, W)``, ``ego`` ``(K, E, 6)``, ``dest`` ``(K, E, 2)`` -> set-points
        ``(K, E, tau_o, 2)``. One frame slot at a time, as the rollouts compute it."""
        k, e, t = grids.shape[:3]
        params = self.params(population, np.arange(k))
        owner = torch.arange(k).repeat_interleave(e)
        slots = []
        for j in range(t):
            frames = np.ascontiguousarray(np.asarray(grids)[:, :, j]).reshape(k * e, *grids.shape[3:])
            feats = self.frame_features(params, owner, frames).view(k, e, -1)
            slots.append(self.grid_part(params, feats))
        return self.head(params, torch.stack(slots, dim=2), ego, dest)
