"""One episode of GridSim-v0 driven by a policy: the loop the drivers of one environment
use (videos, ``gridsim run``, the closed-loop evaluation, rollouts of trained networks, the
window recorder), and the one summary of how it went. The trainer's fitness rollouts step
many environments in lockstep instead (:class:`neurotrajectory.evolve.fitness.Evaluator`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gridsim.errors import GridSimError
from gridsim.vehicle.kinematics import V

#: ``policy(env, obs, info) -> action``.
Policy = Callable[..., object]


@dataclass
class Episode:
    """The steps of one episode: the reset's info and one info per step, each with its
    ``"reward"`` (the fitness vector ``[l1, l2, l3]``)."""

    start: dict
    infos: list[dict]
    #: what ended it: "collision", "off road", "destination reached", "time limit" (the
    #: scenario's duration) or "steps limit" (the steps asked for ran out first)
    ended_by: str = ""

    @property
    def steps(self) -> int:
        return len(self.infos)

    @property
    def last(self) -> dict:
        """The last step's info (the reset's before any step)."""
        return self.infos[-1] if self.infos else self.start

    @property
    def fitness(self) -> np.ndarray:
        """The fitness vector summed over the steps ``(3,)``."""
        return np.sum([i["reward"] for i in self.infos], axis=0) if self.infos else np.zeros(3)

    @property
    def failed(self) -> bool:
        """Ended in a collision or off the road."""
        return bool(self.last.get("collision") or self.last.get("off_road"))

    def poses(self) -> np.ndarray:
        """The ego's poses ``(steps + 1, 5)`` ``[x, y, psi, v, delta]`` (world frame, rear
        axle), from the reset on."""
        return np.array([self.start["pose"], *(i["pose"] for i in self.infos)])

    def summary(self) -> dict:
        """Steps, simulated time [s], distance driven [m], how it ended, mean speed [m/s]
        and the fitness sums."""
        poses = self.poses()
        fitness = self.fitness
        last = self.last
        return {
            "steps": self.steps,
            "simulated_s": float(last.get("time", 0.0)),
            "distance_m": float(np.sum(np.hypot(*np.diff(poses[:, :2], axis=0).T))),
            "collision": bool(last.get("collision", False)),
            "off_road": bool(last.get("off_road", False)),
            "destination_reached": bool(last.get("destination_reached", False)),
            "ended_by": self.ended_by,
            "mean_speed": float(np.mean(poses[1:, V])) if self.infos else 0.0,
            "fitness_sums": {
                "l1": float(fitness[0]),
                "l2": float(fitness[1]),
                "l3": float(fitness[2]),
            },  # fmt: skip
        }


def check_steps(steps: int | None) -> None:
    """A :class:`GridSimError` unless ``steps`` is None (no limit) or >= 1."""
    if steps is not None and steps < 1:
        raise GridSimError(f"steps must be >= 1, got {steps}")


def run_episode(
    env,
    policy: Policy,
    steps: int | None = None,
    seed: int | None = None,
    on_step: Callable[[object, dict], None] | None = None,
    on_reset: Callable[[object, dict], None] | None = None,
) -> Episode:
    """Reset ``env`` with ``seed`` and step ``policy`` until the episode ends (terminated or
    truncated) or after ``steps`` decisions (None: no limit). ``on_reset(env, info)`` is
    called after the reset, ``on_step(env, info)`` after every step, its ``info`` with the
    step's ``"reward"`` and whether it ``"truncated"`` the episode (the scenario's duration,
    or a wrapper's limit such as gymnasium's ``TimeLimit``)."""
    check_steps(steps)
    obs, info = env.reset(seed=seed)
    episode = Episode(start=info, infos=[])
    if on_reset is not None:
        on_reset(env, info)
    terminated = truncated = False
    while steps is None or episode.steps < steps:
        obs, reward, terminated, truncated, info = env.step(policy(env, obs, info))
        info = {**info, "reward": np.asarray(reward), "truncated": bool(truncated)}
        episode.infos.append(info)
        if on_step is not None:
            on_step(env, info)
        if terminated or truncated:
            break
    last = episode.last
    episode.ended_by = (  # (destination reached ends an episode only if it terminated it:
        # with env.end_at_destination off, the time limit does)
        "collision" if last.get("collision") else "off road" if last.get("off_road")
        else "destination reached" if last.get("destination_reached") and terminated
        else "time limit" if episode.infos and truncated else "steps limit"
    )  # fmt: skip
    return episode
