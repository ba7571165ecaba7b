"""``neurotrajectory rollout``: drive a member of a run's front and export a video."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gridsim.cli.flags import at_least, overlay_flag, seed_flag
from neurotrajectory.cli.flags import (
    check_video,
    episode_seconds,
    pick_flag,
    plan_smoothing_flag,
    run_flag,
)


def add_parser(sub) -> None:
    p = sub.add_parser("rollout", help="drive a Pareto-front member and export a video")
    run_flag(p)
    pick_flag(p)
    p.add_argument("--video", default="rollout.mp4",
                   help="video to write (.mp4 or .gif; default %(default)s, replacing a file "
                   "there once the video is complete)")  # fmt: skip
    overlay_flag(p)
    seed_flag(
        p,
        "episode seed (default: the run's first held-out episode, which train "
        "--video films; an even seed is one its generations trained on)",
        default=None,
    )
    p.add_argument(
        "--steps",
        type=at_least(1),
        default=None,
        help="decisions to drive at most (default: the whole episode)",
    )
    p.add_argument("--seconds", type=episode_seconds, default=None, metavar="S",
                   help="episode length [s] (default: the run's; heldout drives its own: see "
                   "episode_seconds in heldout.json)")  # fmt: skip
    p.add_argument("--track", default=None, metavar="NAME",
                   help="recorded scenes: drive this track as the ego (as heldout.json names "
                   "it: the id, or FILE/ID on a collection of scenes; default: as the run's "
                   "generations, one of its training tracks)")  # fmt: skip
    plan_smoothing_flag(p, "drive with this plan smoothing instead of the run's (as heldout "
                        "--plan-smoothing)")  # fmt: skip
    p.set_defaults(func=execute)


def execute(args: argparse.Namespace) -> int:
    check_video(args.video)
    seed = args.seed
    if seed is None:  # an episode no generation trained on
        from neurotrajectory.evolve.runs import Run

        seed = Run.open(args.run).config.heldout_seeds(1)[0]
    rollout(args.run, args.pick, args.video, seed, args.steps, args.overlay, args.seconds,
            args.track, args.plan_smoothing)  # fmt: skip
    return 0


def rollout(
    run_dir: str,
    pick: str,
    video: str,
    seed: int,
    steps: int | None,
    overlay: bool = True,
    seconds: float | None = None,
    track: str | None = None,
    smoothing: float | None = None,
) -> dict:
    """Drive the front member ``pick`` of the run ``run_dir`` for at most ``steps`` decisions
    on the episode ``seed`` (``seconds`` long, default the run's; the ego driving the recorded
    ``track``, default as the run's generations; a held-out episode of ``heldout.json`` is
    its seed, track, episode_seconds and plan_smoothing) into ``video``, the plans smoothed
    as the run's (or by ``smoothing``); print and return a summary."""
    from gridsim.video import episode_name, record_episode
    from neurotrajectory.compare.front import episode_env, load_front_member

    run, policy, member = load_front_member(run_dir, pick, smoothing)
    env = episode_env(run, seconds, track, render_mode="rgb_array")
    episode = env.cfg.episode_decisions
    if steps and steps > episode:
        print(f"neurotrajectory: note: --steps {steps} is more than the episode's "
              f"{episode} decisions ({env.cfg.simulation.duration:g} s; --seconds makes it "
              f"longer): the episode ends at {episode}", file=sys.stderr)  # fmt: skip
    name = f"NeuroTrajectory, {pick} member {member['member']} of {Path(run_dir).name}"

    def label(env) -> str:  # the scene, the track and the seed: to drive it again
        return f"{name}: {episode_name(env, seed)}"

    driven, path = record_episode(env, policy, video, min(steps or episode, episode), seed=seed,
                                  overlay=overlay, label=label)  # fmt: skip
    s = driven.summary()
    result = {"video": str(path), "member": member, **s}
    f = s["fitness_sums"]
    ended = {"collision": "a collision", "off road": "leaving the road",
             "destination reached": "reaching the destination", "time limit": "its time limit",
             "steps limit": "the --steps limit"}[s["ended_by"]]  # fmt: skip
    on = f", track {track}" if track else ""
    print(f"{pick} member {member['member']}, seed {seed}{on}: {s['steps']} decisions, "
          f"{s['simulated_s']:.1f} s, {s['distance_m']:.0f} m at {s['mean_speed']:.1f} m/s, "
          f"ended by {ended}\n"
          f"  fitness sums: l1 {f['l1']:.4g} m^2, l2 {f['l2']:.3g} rad/s, l3 {f['l3']:.4g} m/s\n"
          f"  video: {path}")  # fmt: skip
    return result
