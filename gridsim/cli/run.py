"""``gridsim run``: drive a built-in policy in GridSim-v0 and summarise the episode."""

from __future__ import annotations

import argparse
import warnings

from gridsim.cli.flags import at_least, overlay_flag, quiet_flag, scenario_flag, seed_flag
from gridsim.errors import GridSimError
from gridsim.outputs import rounded, summary_text
from gridsim.policies import POLICIES
from gridsim.scenario.family import is_recorded


def add_parser(sub) -> None:
    p = sub.add_parser("run", help="drive a policy in GridSim-v0, print a summary, export a video")
    scenario_flag(p, default="seamless")
    p.add_argument("--steps", type=at_least(1), default=300, help="decisions to run at most")
    p.add_argument(
        "--policy",
        default="reference",
        choices=list(POLICIES),
        help="the driver: the human reference, lane following, random (controls drawn uniformly "
        "from the action space: it brakes on average and soon stands) or idle",
    )
    seed_flag(p)
    p.add_argument("--track", default=None, metavar="ID",
                   help="recorded scenes: the track the ego drives (default: one drawn from "
                   "the seed; the summary names it)")  # fmt: skip
    p.add_argument("--video", default=None, help="write a video (.mp4, or .gif)")
    overlay_flag(p)
    quiet_flag(p)
    p.set_defaults(func=execute)


def execute(args: argparse.Namespace) -> int:
    summary = run_policy(
        args.scenario, args.policy, args.steps, args.seed, video=args.video,
        progress=not args.quiet, overlay=args.overlay, track=args.track,
    )  # fmt: skip
    print(summary_text(rounded(summary)))
    return 0


def run_policy(
    scenario: str,
    policy: str,
    steps: int,
    seed: int = 0,
    video: str | None = None,
    progress: bool = True,
    overlay: bool = True,
    track: str | None = None,
) -> dict:
    """Run ``policy`` for up to ``steps`` decisions (on a recorded scene with the ego on
    ``track``, if given); optionally write a video. Returns a summary: distance driven,
    collisions, off-road, fitness sums and the episode outcome (on a recorded scene, the
    ego's track and how long it lasts: its episode lasts at most that)."""
    from gridsim.envs.gridsim_env import GridSimEnv
    from gridsim.outputs import progress_bar
    from gridsim.video import episode_name, record_episode, video_problem

    if policy not in POLICIES:
        raise GridSimError(f"unknown policy {policy!r}; choose from {sorted(POLICIES)}")
    if steps < 1:
        raise GridSimError(f"--steps must be >= 1, got {steps}")
    if video is not None and (problem := video_problem(video)):
        raise GridSimError(f"--video {video}: {problem}")  # before any work
    pol = POLICIES[policy]()
    ego = {"ego": {"track": str(track)}} if track is not None else {}
    with warnings.catch_warnings(record=True) as said:  # (given after the check below: a
        warnings.simplefilter("always")  # warning that ego.track is ignored, then the error)
        try:
            env = GridSimEnv(scenario, render_mode="rgb_array" if video else None,
                             action_type=pol.action_type, **ego)  # fmt: skip
            failure = None
        except Exception as exc:  # (raised after the warnings that came before it)
            failure = exc
    generated = failure is None and track is not None and not is_recorded(env.scenario)
    for w in said:
        if not (generated and "ego.track" in str(w.message)):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if failure is not None:
        raise failure
    if generated:
        raise GridSimError(f"--track {track}: {scenario} is a generated scenario, it has no "
                           "recorded tracks to drive (drop --track)")  # fmt: skip
    env.action_space.seed(seed)
    bar = progress_bar(
        total=steps, desc=f"{policy} on {scenario}", unit="step", disable=not progress
    )

    def stepped(env, info) -> None:  # (a collection's scene is drawn at the reset)
        if bar.n == 0:  # the episode's own length, when shorter (a recorded track's)
            bar.total = min(steps, round(env.time_limit / env.cfg.env.decision_period))
        bar.set_description(f"{policy} on {env.scenario.name}", refresh=False)
        bar.update()

    def label(env) -> str:
        return f"{policy} policy, {episode_name(env, seed)}"

    episode, path = record_episode(env, pol, video, steps, seed, on_step=stepped,
                                   overlay=overlay, label=label)  # fmt: skip
    bar.close()
    s = episode.summary()
    summary = {"scenario": env.scenario.name, "policy": policy, "seed": seed,
               "episode_seed": env.episode_seed, **s,
               "simulated_s": round(s["simulated_s"], 3),
               "distance_m": round(s["distance_m"], 2)}  # fmt: skip
    recorded = env.world.ego_track
    if recorded is not None:  # (its episode lasts at most as long as the human's track)
        summary |= {"ego_track": recorded.track_id,
                    "ego_track_s": round(float(recorded.duration), 3)}  # fmt: skip
    if path is not None:
        summary["video"] = str(path)
    return summary
