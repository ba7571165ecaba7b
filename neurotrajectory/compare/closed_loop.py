"""Closed-loop driving: a policy drives GridSim-v0 episodes, and how well it went.

Per episode: ``completed`` (ran to its time limit or destination without collision or
leaving the road), ``progress`` (distance driven over the distance the human reference drove
in the same time; NaN when the human drove less than :data:`MIN_HUMAN_PATH`, and left out
of the mean), collision, off-road, time driven [s], mean speed [m/s], mean steering rate
[rad/s] and the episode's fitness vector ``[l1, l2, l3]``.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from gridsim.envs.gridsim_env import GridSimEnv
from gridsim.video import record_episode
from neurotrajectory.data.windows import goal_overrides

#: m: below this the human's path (a car waiting at a light) is no yardstick for progress.
MIN_HUMAN_PATH = 1.0


def _length(points: np.ndarray) -> float:
    return float(np.sum(np.hypot(*np.diff(points, axis=0).T)))


def drive_episodes(
    scenario: str,
    policy,
    seeds: list[int],
    seconds: float,
    video: Path | None = None,
    ego: dict | None = None,
    goal_seconds: float | None = None,
    label: str | None = None,
    progress: Callable[[int], None] | None = None,
) -> list[dict]:
    """One row of statistics per episode of ``policy`` on ``scenario`` (episodes of
    ``seconds``, one per seed; ``ego`` overrides the scenario's ego section, ``goal_seconds``
    its ``env.goal_seconds``); with ``video``, the first episode is also exported there,
    annotated with ``label`` as the driver's name and the episode's seed. ``progress(1)``
    after each episode."""
    more = ({"ego": ego} if ego else {}) | goal_overrides(goal_seconds)
    env = GridSimEnv(scenario, action_type=policy.action_type,
                     render_mode="rgb_array" if video else None,
                     simulation={"duration": seconds}, **more)  # fmt: skip
    dt = env.cfg.simulation.dt
    rows = []
    for k, seed in enumerate(seeds):
        named = None if label is None else f"{label}, seed {seed}"  # (drives it again)
        episode, _ = record_episode(env, policy, video if k == 0 else None, seed=seed,
                                    label=named)  # fmt: skip
        s, fitness = episode.summary(), episode.fitness
        ref = env.reference
        driven = np.vstack([ref.xy[:1], episode.poses()[1:, :2]])
        human = ref.positions(np.arange(0.0, s["simulated_s"] + 1e-9, dt))
        rows.append({
            "seed": int(seed),
            "completed": float(not episode.failed),
            "progress": _progress(_length(driven), _length(human)),
            "collision": float(s["collision"]),
            "off_road": float(s["off_road"]), "seconds": s["simulated_s"],
            "mean_speed": s["mean_speed"],
            # l2 sums |steering rate| [rad/s] over the ticks: its mean a tick
            "mean_steer_rate": float(fitness[1] * dt / s["simulated_s"]) if s["simulated_s"]
                               else 0.0,
            "l1": float(fitness[0]), "l2": float(fitness[1]), "l3": float(fitness[2]),
        })  # fmt: skip
        if progress is not None:
            progress(1)
    return rows


def _progress(driven: float, human: float) -> float:
    return driven / human if human >= MIN_HUMAN_PATH else float("nan")


def summarise(rows: list[dict]) -> dict:
    """The mean of every statistic over ``rows`` (NaN entries left out; NaN if all are),
    and the number of episodes (labels, as the seed or the track, are left out)."""
    keys = [k for k, v in rows[0].items() if k != "seed" and not isinstance(v, str)]
    out = {}
    for k in keys:
        values = np.array([r[k] for r in rows], dtype=np.float64)
        kept = values[~np.isnan(values)]
        out[k] = float(kept.mean()) if len(kept) else float("nan")
    return out | {"episodes": len(rows)}


def closed_loop(
    scenario: str,
    policy,
    seeds: list[int],
    seconds: float,
    video: Path | None = None,
    goal_seconds: float | None = None,
    label: str | None = None,
    tracks: list[str] | None = None,
) -> dict:
    """Mean closed-loop statistics of ``policy`` over ``seeds`` on ``scenario``, with the rows
    of its episodes (:func:`drive_episodes`) under ``"per_episode"``; ``label``: the driver's
    name in the video. With ``tracks`` (ids of a recorded scene), the ego drives each of them
    once, with the seeds in turn, and each row names its ``track``."""
    if tracks is None:
        rows = drive_episodes(scenario, policy, seeds, seconds, video,
                              goal_seconds=goal_seconds, label=label)  # fmt: skip
        return summarise(rows) | {"per_episode": rows}
    named = {track: None if label is None else f"{label}, track {track}" for track in tracks}
    rows = [{**row, "track": track}
            for k, (track, seed) in enumerate(zip(tracks, seeds, strict=True))
            for row in drive_episodes(scenario, policy, [seed], seconds,
                                      video if k == 0 else None, ego={"track": track},
                                      goal_seconds=goal_seconds, label=named[track])]  # fmt: skip
    return summarise(rows) | {"per_episode": rows}
