"""The NeuroTrajectory network: per-grid CNN -> FC -> FC -> one LSTM branch per set-point.

Input: a GridSim-v0 observation (``grids`` uint8 ``(tau_i, H, W)``, ``ego`` ``(6,)``,
``destination`` ``(2,)``), batched. Output: ``(batch, tau_o, 2)`` set-points [m] in the grid
frame, i.e. directly the environment's trajectory action.

Each grid goes through the same CNN (three stride-2 convolutions); its features, with the
ego state and the destination, go through FC ``fc1`` and FC ``fc2`` (sigmoid by default, as
in the paper). Branch ``i`` is a many-to-one LSTM over the ``tau_i`` per-frame features and
a linear read-out of set-point ``i``. The output is a residual on a kinematic prior
(``NetConfig.prior``): ``"destination_curve"`` (the default: the feasible arc to the given
destination, :mod:`neurotrajectory.curves`), ``"constant_velocity"`` (where the ego would be
at constant speed and heading) or ``"none"``; with a prior a freshly initialised network
already drives forward.

The residual is read out in the ego frame (``NetConfig.frame = "ego"``: x along the heading,
y to the left; rotated into the grid frame before it is added to the prior), so that "slow
down" or "keep left" is the same output whatever the heading. With ``NetConfig.skip`` a
linear read-out of the :func:`kinematic_features` (speed, acceleration, steering, the
destination and the prior's set-points, all in the ego frame) is added to each branch's
residual: the speed profile a human adds to the prior is mostly a function of these few
numbers. Both read-outs start at 0.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, astuple, dataclass
from enum import Enum

import numpy as np
import torch
from torch import nn

from gridsim.envs.plan_smoothing import PlanSmoother, check_keep
from gridsim.frames import EGO_ACCEL, EGO_COS, EGO_SIN, EGO_SPEED, EGO_STEERING
from gridsim.sensors.occupancy_kernels import block_sums, pooled_convolution
from neurotrajectory.curves import CurveLimits, destination_curves

ACTIVATIONS = {"sigmoid": nn.Sigmoid, "relu": nn.ReLU, "tanh": nn.Tanh}
#: The frames of the network's residual on its prior (:attr:`NetConfig.frame`): ``ego``,
#: along and across the heading; ``grid``, the grid's axes.
FRAMES = ("ego", "grid")
DESTINATION_SCALE = 20.0  # m: destination inputs are divided by this


def constant_velocity_setpoints(ego: torch.Tensor, times: torch.Tensor) -> torch.Tensor:
    """Where the ego would be at ``times`` [s] holding its speed and heading: ``(B, T, 2)`` [m,
    grid frame] from ``ego`` ``(B, 6)`` (speed, ..., cos, sin of the heading)."""
    speed, cos, sin = (ego[:, k : k + 1] for k in (EGO_SPEED, EGO_COS, EGO_SIN))
    dist = speed * times[None, :]
    return torch.stack([dist * cos, dist * sin], dim=2)


def to_ego_frame(xy: torch.Tensor, ego: torch.Tensor) -> torch.Tensor:
    """Points ``(B, ..., 2)`` [m, grid frame] in the ego frame (x along the heading, y to the
    left), with the heading's cos, sin from ``ego`` ``(B, 6)``."""
    shape = (-1,) + (1,) * (xy.dim() - 2)
    cos, sin = ego[:, EGO_COS].reshape(shape), ego[:, EGO_SIN].reshape(shape)
    x, y = xy[..., 0], xy[..., 1]
    return torch.stack([x * cos + y * sin, y * cos - x * sin], dim=-1)


def from_ego_frame(xy: torch.Tensor, ego: torch.Tensor) -> torch.Tensor:
    """The inverse of :func:`to_ego_frame`."""
    shape = (-1,) + (1,) * (xy.dim() - 2)
    cos, sin = ego[:, EGO_COS].reshape(shape), ego[:, EGO_SIN].reshape(shape)
    x, y = xy[..., 0], xy[..., 1]
    return torch.stack([x * cos - y * sin, x * sin + y * cos], dim=-1)


def kinematic_features(cfg: NetConfig, ego, dest, prior) -> torch.Tensor:
    """The skip read-out's inputs ``(B, 5 + 2 tau_o)``, heading-invariant and of order 1:
    speed / v_max, steering [rad], acceleration / a_max, then the destination and the prior's
    set-points (``prior`` ``(B, tau_o, 2)`` or None: zeros) in the ego frame /
    :data:`DESTINATION_SCALE`. Not the steering rate: in closed loop it is the network's own
    last correction, and feeding it back makes the steering oscillate (measured: 7 rad/s
    mean steering rate on inner-city with it, 0.3 without)."""
    a_max, _, v_max, _ = cfg.limits
    b = ego.shape[0]
    if prior is None:
        prior = ego.new_zeros(b, cfg.horizon, 2)
    points = to_ego_frame(torch.cat([dest[:, None, :], prior], dim=1), ego)
    state = torch.stack(
        [ego[:, EGO_SPEED] / v_max, ego[:, EGO_STEERING], ego[:, EGO_ACCEL] / a_max], dim=1
    )
    return torch.cat([state, points.reshape(b, -1) / DESTINATION_SCALE], dim=1)


def _destination_curve_prior(cfg: NetConfig, ego, dest, times) -> torch.Tensor:
    curves = destination_curves(ego.numpy(), dest.numpy(), times.numpy(), cfg.curve_limits,
                                cfg.goal_seconds)  # fmt: skip
    return torch.from_numpy(curves)


#: The kinematic priors the network's output is a residual on: ``(cfg, ego (B, 6), dest
#: (B, 2), times (T,)) -> (B, T, 2)`` [m, grid frame], each row computed on its own (the
#: same result in any batch); None: no prior.
PRIORS = {
    "destination_curve": _destination_curve_prior,
    "constant_velocity": lambda cfg, ego, dest, times: constant_velocity_setpoints(ego, times),
    "none": None,
}


def prior_setpoints(cfg: NetConfig, ego, dest, times) -> torch.Tensor | None:
    """The set-points of ``cfg.prior`` (see :data:`PRIORS`), or None."""
    prior = PRIORS[cfg.prior]
    return None if prior is None else prior(cfg, ego, dest, times)


@dataclass(frozen=True)
class NetConfig:
    """Sizes of the network. ``pool`` downsamples the grids before the CNN (1 = none).
    ``limits`` are the ego's (:class:`~neurotrajectory.curves.CurveLimits` fields: a_max,
    b_max, v_max, max_curvature) for the destination-curve prior; the scenario sets them
    (:func:`~neurotrajectory.evolve.fitness.net_config_for`)."""

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
    prior: str = "destination_curve"
    limits: tuple[float, float, float, float] = astuple(CurveLimits())
    frame: str = "ego"  # the residual's frame: "ego" (heading-aligned) or "grid"
    skip: bool = True  # add a linear read-out of the kinematic features
    #: closed loop: the share of the previous plan kept in each plan the car follows
    #: (:mod:`gridsim.envs.plan_smoothing`; 0: every plan as the network gives it)
    smoothing: float = 0.0
    #: how far ahead the destination input lies [s] (the scenario's ``env.goal_seconds``);
    #: None: at the last set-point
    goal_seconds: float | None = None
    #: the largest correction to the prior [m] along and across the heading (ego frame):
    #: the residual ``r`` becomes ``bound * tanh(r / bound)``, so that a network off the
    #: states it learnt from cannot swing its plan off the road; None: unbounded
    max_correction: tuple[float, float] | None = None

    #: Fields left out of :meth:`to_dict` while None (configurations saved before they
    #: existed read and compare the same).
    UNSET_UNSAVED = ("goal_seconds", "max_correction")

    #: What configurations saved before ``frame`` and ``skip`` existed meant.
    LEGACY = {"frame": "grid", "skip": False}

    @classmethod
    def from_dict(cls, d: dict) -> NetConfig:
        """A saved configuration (:meth:`to_dict`); keys it predates take their old values."""
        return cls(**{**cls.LEGACY, **d})

    @property
    def features(self) -> int:
        """Width of :func:`kinematic_features`."""
        return 5 + 2 * self.horizon

    def __post_init__(self) -> None:
        object.__setattr__(self, "channels", tuple(self.channels))
        object.__setattr__(self, "limits", tuple(float(x) for x in self.limits))
        if self.activation not in ACTIVATIONS:
            raise ValueError(
                f"activation must be one of {sorted(ACTIVATIONS)}, got {self.activation!r}"
            )
        if self.prior not in PRIORS:
            raise ValueError(f"prior must be one of {list(PRIORS)}, got {self.prior!r}")
        if self.frame not in FRAMES:
            raise ValueError(f"frame must be one of {list(FRAMES)}, got {self.frame!r}")
        object.__setattr__(self, "smoothing", check_keep(self.smoothing, "smoothing"))
        if self.max_correction is not None:
            bound = checked_max_correction(self.max_correction, self.frame)
            object.__setattr__(self, "max_correction", bound)
        if self.grid_size % (self.pool * 8):
            raise ValueError(
                f"grid_size {self.grid_size} must be divisible by pool * 8 = {self.pool * 8}"
            )

    def to_dict(self) -> dict:
        """The fields, less those of :attr:`UNSET_UNSAVED` that are None."""
        d = asdict(self)
        for name in self.UNSET_UNSAVED:
            if d[name] is None:
                del d[name]
        return d

    @property
    def curve_limits(self) -> CurveLimits:
        return CurveLimits(*self.limits)


def checked_max_correction(bound, frame: str) -> tuple[float, float]:
    """``bound`` (:attr:`NetConfig.max_correction`) as two floats [m], or a ``ValueError``
    saying why it cannot bound the correction of a network whose residual is in ``frame``."""
    try:
        pair = tuple(float(b) for b in bound)
    except (TypeError, ValueError):
        pair = ()
    if len(pair) != 2 or not all(math.isfinite(b) and b > 0 for b in pair):
        raise ValueError("max_correction must be two finite numbers > 0 [m] (along, across "
                         f"the heading), got {bound!r}")  # fmt: skip
    if frame != "ego":
        raise ValueError("max_correction bounds the correction in the ego frame: it needs "
                         f"frame 'ego', got {frame!r}")  # fmt: skip
    return pair


#: ``paper``: the full FC 1024 / 512 on 128 x 128 grids (about 19 M parameters);
#: ``default``: pooled 64 x 64 grids and FC 256 / 128, trains in minutes on 2 CPU cores.
PRESETS = {
    "paper": NetConfig(pool=1, channels=(16, 32, 64), fc1=1024, fc2=512, lstm=128),
    "default": NetConfig(),
    "tiny": NetConfig(pool=4, channels=(4, 8, 8), fc1=32, fc2=32, lstm=8),
}


#: What evolution mutates, by parameter-name prefix (None: every weight). ``head``: the LSTM
#: branches and both read-outs, on an encoder the warm start fitted; ``readout``: only the
#: branches' linear read-outs and the kinematic skip read-out (a few hundred weights).
EVOLVE_SCOPES = {
    "all": None,
    "head": ("branches.", "skip_weight"),
    "readout": ("branches.head_weight", "branches.head_bias", "skip_weight"),
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
        act = ACTIVATIONS[cfg.activation]
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


class TrajectoryNet(nn.Module):
    """See the module docstring."""

    def __init__(self, cfg: NetConfig) -> None:
        super().__init__()
        self.cfg = cfg
        self.encoder = GridEncoder(cfg)
        self.branches = BranchLSTMs(cfg.horizon, cfg.fc2, cfg.lstm)
        if cfg.skip:  # per set-point, (x, y) from the kinematic features
            self.skip_weight = nn.Parameter(torch.zeros(cfg.horizon, 2, cfg.features))
        times = cfg.setpoint_period * torch.arange(1, cfg.horizon + 1, dtype=torch.float32)
        self.register_buffer("times", times, persistent=False)

    def evolved(self, scope: str) -> tuple[str, ...] | None:
        """The parameters evolution mutates in ``scope`` (see :data:`EVOLVE_SCOPES`), or None
        for all of them."""
        prefixes = EVOLVE_SCOPES[scope]
        if prefixes is None:
            return None
        return tuple(name for name, _ in self.named_parameters() if name.startswith(prefixes))

    @property
    def zero_init(self) -> tuple[str, ...]:
        """Parameters that start at 0 (:func:`~neurotrajectory.evolve.genome.initial_genome`): the
        skip read-out and, with a prior, the branches' read-out, so that a fresh network
        outputs its prior exactly."""
        skip = ("skip_weight",) if self.cfg.skip else ()
        return skip if self.cfg.prior == "none" else ("branches.head_weight", *skip)

    def forward(
        self, grids: torch.Tensor, ego: torch.Tensor, destination: torch.Tensor
    ) -> torch.Tensor:
        """``grids`` uint8 or float ``(B, tau_i, H, W)``; ``ego`` ``(B, 6)``; ``destination``
        ``(B, 2)`` [m]. Returns set-points ``(B, tau_o, 2)`` [m]."""
        out = self.branches(self.encoder(grids, ego, destination))
        prior = prior_setpoints(self.cfg, ego.detach(), destination.detach(), self.times)
        if self.cfg.skip:
            feats = kinematic_features(self.cfg, ego, destination, prior)
            out = out + torch.einsum("bf,tcf->btc", feats, self.skip_weight)
        return finish_setpoints(self.cfg, out, prior, ego)


def finish_setpoints(cfg: NetConfig, residual, prior, ego) -> torch.Tensor:
    """Set-points [m, grid frame] from the ``residual`` ``(B, tau_o, 2)`` (in ``cfg.frame``)
    and the ``prior`` (grid frame, or None)."""
    if cfg.max_correction is not None:  # element-wise: the same bits in any batch
        bound = torch.tensor(cfg.max_correction, dtype=residual.dtype)
        residual = torch.tanh(residual / bound) * bound
    if cfg.frame == "ego":
        residual = from_ego_frame(residual, ego)
    return residual if prior is None else residual + prior


def observation_tensors(obs: dict | list[dict]) -> tuple[torch.Tensor, ...]:
    """Batch GridSim-v0 observations (one dict or a list) into the network's inputs."""
    if isinstance(obs, dict):
        obs = [obs]
    grids = torch.from_numpy(np.stack([o["grids"] for o in obs]))
    ego = torch.from_numpy(np.stack([o["ego"] for o in obs]).astype(np.float32))
    dest = torch.from_numpy(np.stack([o["destination"] for o in obs]).astype(np.float32))
    return grids, ego, dest


def count_parameters(net: nn.Module) -> int:
    """The network's number of weights: the length of its genome."""
    return sum(p.numel() for p in net.parameters())


def window_inputs(windows, index: np.ndarray) -> tuple[torch.Tensor, ...]:
    """The network's inputs for ``windows[index]`` (a :class:`~neurotrajectory.data.windows.Windows`
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
# individual never depends on which or how many other individuals are in the batch, nor on
# where in the batch it sits:
#
# * every matrix product is a ``torch.bmm`` item of a fixed shape per individual (one item
#   per individual with all ``E`` rows, finished episodes included: MKL does not compute a
#   row alike for different row counts), and every convolution one ``conv2d`` call per
#   individual on its ``E`` frames, or, from the first or the second convolution on, one
#   grouped call for the batch, the first one possibly compiled (each output's sum in
#   ``conv2d``'s order), where a probe shows it gives those bits (and is the faster;
#   :meth:`PopulationNet.convolutions`);
# * MKL's result for an item also depends on the 64-byte alignment of its operands, so every
#   item starts at the same alignment: weights live in 64-byte aligned rows (the population
#   store, and a per-batch copy of the small parameters, each at an aligned offset), and
#   activations are copied into aligned rows when they are not;
# * element-wise functions are exact (add, mul, relu) or computed alike at every position
#   of a tensor (``exp`` and ``tanh`` use vectorised kernels with masked tails);
#   ``torch.sigmoid`` is not (its scalar tail loop rounds differently), so the sigmoid is
#   ``1 / (1 + exp(-x))``;
# * average pooling sums the integer cell values exactly and scales once.
#
# The result differs from :class:`TrajectoryNet` by float rounding only (about 1e-7 m on the
# set-points; asserted in the tests). Training and its fitness use this path only.

_CONVS = ((2, 2), (2, 1), (2, 1))  # stride, padding of GridEncoder.cnn's convolutions
_CONV_NAMES = ("encoder.cnn.0", "encoder.cnn.2", "encoder.cnn.4")


class Convolutions(Enum):
    """How :meth:`PopulationNet.frame_features` runs the CNN's convolutions for a batch of
    individuals (:meth:`PopulationNet.convolutions`' choice)."""

    PER_INDIVIDUAL = "one call per individual and convolution"
    GROUPED = "every convolution one grouped call for all individuals"
    GROUPED_AFTER_FIRST = "the first per individual, the others grouped"
    #: the pooling and the first in one compiled call
    #: (:func:`~gridsim.sensors.occupancy_kernels.pooled_convolution`), the others grouped
    COMPILED_FIRST = "the first compiled, the others grouped"

    @property
    def first_grouped(self) -> int:
        """The first convolution in the grouped call of :attr:`GROUPED` (0) and
        :attr:`GROUPED_AFTER_FIRST` (1)."""
        return {"GROUPED": 0, "GROUPED_AFTER_FIRST": 1}[self.name]


ALIGN = 16  # floats: 64 bytes
#: Parameters of at least this many numbers are not copied per batch: products with them
#: run on views into the population store, one ``bmm`` per run of consecutive individuals.
BIG_PARAMETER = 1 << 19


def _padded(n: int) -> int:
    return -(-n // ALIGN) * ALIGN


def aligned_rows(k: int, n: int) -> torch.Tensor:
    """An uninitialised ``(k, n)`` float32 view whose rows start at 64-byte boundaries."""
    return torch.empty(k, _padded(n))[:, :n]


def _is_aligned(x: torch.Tensor) -> bool:
    """Whether every item ``x[i]`` of a tensor with contiguous items starts 64-byte aligned."""
    return (
        x.data_ptr() % 64 == 0
        and (x.shape[0] < 2 or x.stride(0) % ALIGN == 0)
        and x[0].is_contiguous()
    )


def _items(x: torch.Tensor) -> torch.Tensor:
    """``x`` with contiguous, 64-byte aligned items (a copy when it is not already so)."""
    if _is_aligned(x):
        return x
    k = x.shape[0]
    out = aligned_rows(k, math.prod(x.shape[1:])).view(x.shape)
    out.copy_(x)
    return out


def _check_blocks(h: int, w: int, p: int) -> None:
    if h % p or w % p:
        raise ValueError(f"grids of {h} x {w} cells do not split into blocks of {p} x {p}")


def block_means(frames: np.ndarray, p: int) -> torch.Tensor:
    """The means of ``p x p`` blocks of ``frames`` uint8 ``(N, H, W)``: float32 ``(N, 1, H / p,
    W / p)``, bit for bit ``avg_pool2d`` of their float values (the integer sums are exact, then
    one division), several times faster: the sums are taken in integers, in one compiled call."""
    n, h, w = frames.shape
    if p == 1:
        return torch.from_numpy(frames).float()[:, None]
    _check_blocks(h, w, p)
    total = np.empty((n, h // p, w // p), np.float32)
    block_sums(np.ascontiguousarray(frames), p, total)
    return torch.from_numpy(total)[:, None].div_(float(p * p))


def _sigmoid(x: torch.Tensor) -> torch.Tensor:
    return torch.reciprocal(torch.exp(-x).add_(1.0))


_PW_ACTIVATIONS = {"sigmoid": _sigmoid, "relu": torch.relu, "tanh": torch.tanh}


def _bmm_t(x: torch.Tensor, w) -> torch.Tensor:
    """``x`` ``(K, M, in)`` times the transpose of ``w`` ``(K, out, in)`` per individual; ``w``
    may be a list of views ``(K_i, out, in)`` covering the K individuals in order."""
    if isinstance(w, torch.Tensor):
        return torch.bmm(_items(x), w.transpose(1, 2))
    outs, a = [], 0
    for part in w:
        b = a + part.shape[0]
        outs.append(torch.bmm(_items(x[a:b]), part.transpose(1, 2)))
        a = b
    return outs[0] if len(outs) == 1 else torch.cat(outs)


def _grouped_convolutions(params: dict) -> dict:
    """The weights and biases of every convolution, of every individual of ``params`` as one
    grouped convolution's (``NAME.grouped``)."""
    out = {}
    for name in _CONV_NAMES:
        weight = params[name + ".weight"]
        out[name + ".grouped"] = (weight.reshape(-1, *weight.shape[2:]),
                                  params[name + ".bias"].reshape(-1))  # fmt: skip
    return out


class PopulationNet:
    """The forward pass of :class:`TrajectoryNet` for a batch of individuals (see above).

    Use: ``store = net.store(population)`` (aligned rows, once), ``params =
    net.params(store, rows)`` for the individuals ``rows`` that still drive, then per step
    :meth:`frame_features` and :meth:`grid_part` for new frames and :meth:`head` for the
    set-points; :meth:`forward` does all at once.
    """

    def __init__(self, cfg: NetConfig) -> None:
        self.cfg = cfg
        template = TrajectoryNet(cfg)
        self.shapes: dict[str, tuple[int, ...]] = {}
        self.offsets: dict[str, int] = {}
        self.small: dict[str, int] = {}  # offsets in the per-batch copy of small parameters
        off = small = 0
        for name, p in template.named_parameters():
            self.shapes[name], self.offsets[name] = tuple(p.shape), off
            off += p.numel()
            if p.numel() < BIG_PARAMETER:
                self.small[name] = small
                small += _padded(p.numel())
        self.size = off
        self.small_size = small
        self.n_cnn = cfg.channels[2] * (cfg.grid_size // cfg.pool // 8) ** 2
        self.times = template.times.clone()
        self.act = _PW_ACTIVATIONS[cfg.activation]
        self._convolutions: dict[tuple[int, int], Convolutions] = {}  # :meth:`convolutions`

    # -- parameters ---------------------------------------------------------------------------
    def store(self, population) -> torch.Tensor:
        """``population`` ``(K, n)`` as a float32 tensor with 64-byte aligned rows (itself when
        it already is one, e.g. a view of :func:`aligned_rows`)."""
        pop = torch.from_numpy(population) if isinstance(population, np.ndarray) else population
        if pop.dtype != torch.float32 or pop.dim() != 2 or pop.shape[1] != self.size:
            raise ValueError(
                f"population must be float32 (K, {self.size}), got {tuple(pop.shape)} {pop.dtype}"
            )
        if pop.stride(1) == 1 and _is_aligned(pop):
            return pop
        out = aligned_rows(*pop.shape)
        out.copy_(pop)
        return out

    def _view(self, rows: torch.Tensor, name: str, offset: int) -> torch.Tensor:
        shape = self.shapes[name]
        return rows[:, offset : offset + math.prod(shape)].view(rows.shape[0], *shape)

    def small_copy(self, store: torch.Tensor) -> torch.Tensor:
        """The small parameters of every row of ``store``, each at a 64-byte aligned offset."""
        out = torch.empty(store.shape[0], self.small_size)
        for name, off in self.small.items():
            self._view(out, name, off).copy_(self._view(store, name, self.offsets[name]))
        return out

    def params(self, store: torch.Tensor, small: torch.Tensor, rows: np.ndarray) -> dict:
        """The parameters of individuals ``rows`` (indices into ``store``, increasing): the
        small ones gathered from ``small`` (:meth:`small_copy` of ``store``), the big ones as
        lists of views into ``store`` (runs of consecutive rows)."""
        rows = np.asarray(rows, dtype=np.int64)
        if len(rows) != store.shape[0]:
            small = small.index_select(0, torch.from_numpy(rows))
        runs = np.split(rows, np.flatnonzero(np.diff(rows) != 1) + 1)
        out = {}
        for name, shape in self.shapes.items():
            if name in self.small:
                out[name] = self._view(small, name, self.small[name])
                continue
            full = self._view(store, name, self.offsets[name])
            if name == "branches.weight_ih":  # used as one (branches * 4h, fc2) matrix
                full = full.reshape(full.shape[0], shape[0] * shape[1], shape[2])
            out[name] = [full[r[0] : r[-1] + 1] for r in runs]
        if "branches.weight_ih" in self.small:
            w = out["branches.weight_ih"]
            out["branches.weight_ih"] = w.reshape(w.shape[0], -1, w.shape[-1])
        return out | self._arranged(out, len(rows))

    def _arranged(self, params: dict, k: int) -> dict:
        """Small weights of ``k`` individuals laid out as the forward pass multiplies them,
        once per batch of individuals instead of every step: the convolutions after the
        convolutions as grouped weights, the branches' recurrent weights ``(K * B, hid, 4h)`` and
        read-outs ``(K * B, 2, hid)`` contiguous (MKL is twice as fast on them as on the
        transposed views)."""
        b, g4, hid = self.shapes["branches.weight_hh"]
        out = {
            "lstm.w_hh": _items(
                params["branches.weight_hh"].reshape(k * b, g4, hid).transpose(1, 2)
            ),
            "lstm.w_head": _items(params["branches.head_weight"].reshape(k * b, 2, hid)),
        }
        return out | _grouped_convolutions(params)

    # -- the forward pass, in three parts -----------------------------------------------------
    def frame_features(self, params: dict, frames: np.ndarray) -> torch.Tensor:
        """CNN features ``(K, E, n_cnn)`` of ``frames`` uint8 ``(K, E, H, W)`` (one frame per
        environment of each individual), computed as :meth:`convolutions` says."""
        k, e = frames.shape[:2]
        plan = self.convolutions(k, e)
        if plan is Convolutions.COMPILED_FIRST:
            return self._features_compiled(params, frames)
        x = self._pooled(frames)
        if plan is Convolutions.PER_INDIVIDUAL:
            return self._features_per_individual(params, x)
        return self._features_grouped(params, x, plan.first_grouped)

    def _pooled(self, frames: np.ndarray) -> torch.Tensor:
        """``frames`` uint8 ``(K, E, H, W)`` pooled and scaled to 0-1: ``(K, E, 1, H/p, W/p)``."""
        k, e, h, w = frames.shape
        p = self.cfg.pool
        return (block_means(frames.reshape(k * e, h, w), p) / 255.0).view(k, e, 1, h // p, w // p)

    def _features_grouped(self, params: dict, x: torch.Tensor, first: int) -> torch.Tensor:
        """:meth:`frame_features` of the pooled frames ``x`` ``(K, E, 1, h, w)``, convolution
        ``first`` and those after it as one grouped call for all individuals (those before,
        one call per individual; ``first`` is 0 or 1)."""
        k, e = x.shape[:2]
        if first == 0:  # (E, K channels, h, w)
            y = x.transpose(0, 1).reshape(e, k, *x.shape[3:])
        else:  # the first convolution per individual
            y = torch.stack([self._conv(x[i], params, _CONV_NAMES[0], i, 0) for i in range(k)], 1)
            y = y.view(e, k * y.shape[2], *y.shape[3:])
        return self._grouped_after(params, y, k, first)

    def _features_compiled(self, params: dict, frames: np.ndarray) -> torch.Tensor:
        """:meth:`frame_features` of ``frames`` uint8 ``(K, E, H, W)``: pooling and the first
        convolution in one compiled call (:func:`~gridsim.sensors.occupancy_kernels.
        pooled_convolution`), the others as one grouped call for all individuals."""
        k, e, h, w = frames.shape
        _check_blocks(h, w, self.cfg.pool)
        name = _CONV_NAMES[0]
        weight = params[name + ".weight"]  # (K, C, 1, kh, kw)
        (stride, pad), p = _CONVS[0], self.cfg.pool
        sizes = zip((h, w), weight.shape[3:], strict=True)
        out = [(n // p + 2 * pad - size) // stride + 1 for n, size in sizes]
        y = torch.empty(e, k * weight.shape[1], *out)
        pooled_convolution(np.ascontiguousarray(frames), p,
                           np.ascontiguousarray(weight[:, :, 0].numpy()),
                           np.ascontiguousarray(params[name + ".bias"].numpy()), stride, pad,
                           y.numpy())  # fmt: skip
        return self._grouped_after(params, y, k, 1)

    def _grouped_after(self, params: dict, y: torch.Tensor, k: int, first: int) -> torch.Tensor:
        """Convolutions ``first`` and after, as one grouped call for the ``k`` individuals, on
        ``y`` ``(E, K * channels, h, w)`` (their input); their features ``(K, E, n_cnn)``."""
        for layer, name in enumerate(_CONV_NAMES[first:], first):
            y = self._conv(y, params, name, None, layer, groups=k)
        e = y.shape[0]
        return y.reshape(e, k, -1).transpose(0, 1).contiguous()

    def _features_per_individual(self, params: dict, x: torch.Tensor) -> torch.Tensor:
        """:meth:`frame_features` of the pooled frames ``x`` ``(K, E, 1, h, w)``, one
        ``conv2d`` call per individual and layer."""
        k, e = x.shape[:2]
        out = torch.empty(k, e, self.n_cnn)
        for i in range(k):  # one call per individual, always on its E frames
            y = x[i]
            for layer, name in enumerate(_CONV_NAMES):
                y = self._conv(y, params, name, i, layer)
            out[i] = y.reshape(e, -1)
        return out

    @staticmethod
    def _conv(x, params: dict, name: str, i: int | None, layer: int, groups: int = 1):
        """Convolution ``layer`` (named ``name``) and its ReLU, of individual ``i``'s weights
        or (``i`` None) of every individual's, as ``groups`` groups."""
        if i is None:
            weight, bias = params[name + ".grouped"]
        else:
            weight, bias = params[name + ".weight"][i], params[name + ".bias"][i]
        stride, pad = _CONVS[layer]
        return torch.nn.functional.conv2d(x, weight, bias, stride, pad, 1, groups).relu_()

    def convolutions(self, k: int, e: int) -> Convolutions:
        """How :meth:`frame_features` of ``k`` individuals on ``e`` frames each runs the
        convolutions (:class:`Convolutions`). Of the choices that give the bits of one call
        per individual, the fastest: a probe on random weights and frames of
        these shapes decides once per ``(k, e)`` (oneDNN picks its kernels by shape and CPU,
        never by values, so every choice it allows gives the same results; only the time
        differs). One frame per individual: one call per individual (torch then convolves
        each individual without oneDNN)."""
        if e < 2:
            return Convolutions.PER_INDIVIDUAL
        if (k, e) not in self._convolutions:
            self._convolutions[(k, e)] = self._probe_convolutions(k, e)
        return self._convolutions[(k, e)]

    def _probe_convolutions(self, k: int, e: int) -> Convolutions:
        """:meth:`convolutions`' probe: the bits of each choice, then the times of those
        that give the bits of one call per individual (the best of 5 runs each)."""
        g = torch.Generator().manual_seed(0)
        params = {}
        for name in _CONV_NAMES:
            w_shape = (k, *self.shapes[name + ".weight"])
            params[name + ".weight"] = 0.2 * torch.randn(w_shape, generator=g)
            params[name + ".bias"] = 0.1 * torch.randn(w_shape[:2], generator=g)
        params |= _grouped_convolutions(params)
        size = self.cfg.grid_size
        frames = torch.randint(0, 256, (k, e, size, size), generator=g, dtype=torch.uint8).numpy()
        x = self._pooled(frames)
        choices = {
            **{
                plan: lambda plan=plan: self._features_grouped(params, x, plan.first_grouped)
                for plan in (Convolutions.GROUPED_AFTER_FIRST, Convolutions.GROUPED)
            },
            Convolutions.COMPILED_FIRST: lambda: self._features_compiled(params, frames),
        }
        reference = self._features_per_individual(params, x)
        allowed = [c for c, run in choices.items() if torch.equal(run(), reference)]
        if len(allowed) < 2:
            return allowed[0] if allowed else Convolutions.PER_INDIVIDUAL
        best = {c: math.inf for c in allowed}
        for _ in range(5):  # alternated, so that a slower moment of the machine hits both
            for c in allowed:
                t0 = time.perf_counter()
                choices[c]()
                best[c] = min(best[c], time.perf_counter() - t0)
        return min(allowed, key=best.__getitem__)

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
        w_hh = params["lstm.w_hh"]
        h = grid.new_zeros(k * b, e, hid)
        c = grid.new_zeros(k * b, e, hid)
        for step in range(t):
            gates = xi[:, :, step].reshape(k * b, e, g4) + torch.bmm(_items(h), w_hh)
            i, f, g, o = gates.chunk(4, dim=2)
            c = _sigmoid(f) * c + _sigmoid(i) * torch.tanh(g)
            h = _sigmoid(o) * torch.tanh(c)
        w_head = params["lstm.w_head"]
        out = _bmm_t(h, w_head).view(k, b, e, 2) + params["branches.head_bias"][:, :, None]
        out = out.permute(0, 2, 1, 3)
        flat_ego, flat_dest = ego.reshape(k * e, -1), dest.reshape(k * e, 2)
        prior = prior_setpoints(self.cfg, flat_ego, flat_dest, self.times)
        if self.cfg.skip:
            feats = kinematic_features(self.cfg, flat_ego, flat_dest, prior).view(k, e, -1)
            w_skip = params["skip_weight"].reshape(k, b * 2, -1)
            out = out + _bmm_t(feats, w_skip).view(k, e, b, 2)
        out = finish_setpoints(self.cfg, out.reshape(k * e, b, 2), prior, flat_ego)
        return out.view(k, e, b, 2)

    def forward(self, population, grids: np.ndarray, ego, dest) -> torch.Tensor:
        """Everything at once (no caching): ``population`` ``(K, n)``, ``grids`` uint8
        ``(K, E, tau_i, H, W)``, ``ego`` ``(K, E, 6)``, ``dest`` ``(K, E, 2)`` -> set-points
        ``(K, E, tau_o, 2)``, computed one frame slot at a time as the rollouts do."""
        store = self.store(population)
        params = self.params(store, self.small_copy(store), np.arange(store.shape[0]))
        t = grids.shape[2]
        slots = []
        for j in range(t):
            frames = np.ascontiguousarray(grids[:, :, j])
            slots.append(self.grid_part(params, self.frame_features(params, frames)))
        return self.head(params, torch.stack(slots, dim=2), ego, dest)


@contextmanager
def one_thread() -> Iterator[None]:
    """Run the block's torch work on one thread (the thread count put back after): the same
    arithmetic, so the same bits, whatever the machine's cores or the caller's setting (a
    worker process sets 1; a command's own process has as many as cores). Also a decorator."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


class NetPolicy:
    """A trained network as a GridSim-v0 policy (trajectory action), its plans smoothed by
    ``smoothing`` (default: the network's ``cfg.smoothing``; see :class:`PlanSmoother`)."""

    action_type = "trajectory"

    def __init__(self, net: TrajectoryNet, smoothing: float | None = None) -> None:
        self.net = net.eval()
        #: the share of the previous plan kept (resolved: the network's unless given)
        self.keep = check_keep(net.cfg.smoothing if smoothing is None else smoothing)
        self.smoother = PlanSmoother(self.keep) if self.keep > 0 else None

    @torch.no_grad()
    @one_thread()
    def __call__(self, env, obs, info):
        plan = self.net(*observation_tensors(obs))[0].numpy()
        return plan if self.smoother is None else self.smoother(env, plan)
